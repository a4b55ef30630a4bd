#include "app/live_run.hpp"

#include "motion_io/readings.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <deque>

namespace cutload::app {

const char* to_string(LiveEnd e) {
    switch (e) {
    case LiveEnd::ProgramEnd: return "program_end";
    case LiveEnd::Stopped: return "stopped";
    case LiveEnd::Idle: return "idle";
    case LiveEnd::Limit: return "limit";
    }
    return "stopped";
}

namespace {

using Clock = std::chrono::steady_clock;
using motion_io::LogReading;

enum class Chan { Pos, X, Y, Z, Feed, Spindle, Block };

bool parse_double(std::string_view text, double& out) {
    while (!text.empty() && text.front() == ' ') text.remove_prefix(1);
    while (!text.empty() && text.back() == ' ') text.remove_suffix(1);
    if (!text.empty() && text.front() == '+') text.remove_prefix(1);
    const auto r = std::from_chars(text.data(), text.data() + text.size(), out);
    return r.ec == std::errc() && r.ptr == text.data() + text.size() && std::isfinite(out);
}

std::string lower(std::string_view s) {
    std::string out(s);
    for (char& c : out) c = char(std::tolower(static_cast<unsigned char>(c)));
    return out;
}

// M30 or M02 (M2) as a word of a block's text: the program's end.
bool block_ends_program(std::string_view text) {
    const std::string t = lower(text);
    for (std::size_t i = 0; i < t.size(); ++i) {
        if (t[i] != 'm' || (i > 0 && std::isalnum(static_cast<unsigned char>(t[i - 1])))) continue;
        std::size_t j = i + 1;
        while (j < t.size() && t[j] == '0') ++j;
        std::size_t k = j;
        while (k < t.size() && std::isdigit(static_cast<unsigned char>(t[k]))) ++k;
        const std::string_view num = std::string_view(t).substr(j, k - j);
        if ((num == "30" || num == "2") && (k == t.size() || !std::isdigit(static_cast<unsigned char>(t[k])))) return true;
    }
    return false;
}

}  // namespace

struct LiveRun::Impl : motion_io::MotionConsumer {
    LiveOptions opt;
    LiveCallbacks cb;
    force_model::StreamingPrediction engine;
    std::unique_ptr<motion_io::IngestChain> chain;
    motion_io::ShdrUnitFactors units;
    // Per channel: the priority (index in the key map's list) of the key that feeds it; a key of
    // higher priority seen later takes over (a live source cannot be scanned ahead as a file is).
    std::vector<std::pair<std::string, std::pair<Chan, std::size_t>>> candidates;
    std::size_t best[7] = {~0u, ~0u, ~0u, ~0u, ~0u, ~0u, ~0u};
    std::int64_t origin_ns = 0;
    bool have_origin = false;
    bool execution_active = false;
    std::size_t observations = 0, force_rows = 0;
    double machine_t_s = 0, last_sample_t_s = 0;
    std::deque<std::pair<double, Clock::time_point>> waiting;   // position readings awaiting their force
    std::vector<double> lags;
    std::vector<LiveGap> gaps;
    force_model::StreamOutput out;
    bool grid_added = false;

    Impl(const LiveOptions& o, const LiveCallbacks& c)
        : opt(o), cb(c), engine(o.spec, make_predict_options(o)) {
        motion_io::ChainOptions co;
        co.step_ms = opt.step_ms;
        co.event_driven = !opt.polled;
        co.clock_batch_readings = opt.clock_batch_readings;
        co.reorder_horizon_s = opt.reorder_horizon_s;
        co.source = "live";
        chain = std::make_unique<motion_io::IngestChain>(co, *this);
        try {
            units = motion_io::shdr_unit_factors(opt.keys);
        } catch (const std::invalid_argument& e) {
            throw motion_io::IngestError(std::string("key map: ") + e.what());
        }
        auto add = [&](const std::vector<std::string>& keys, Chan ch) {
            for (std::size_t i = 0; i < keys.size(); ++i) candidates.push_back({keys[i], {ch, i}});
        };
        add(opt.keys.position, Chan::Pos);
        add(opt.keys.x, Chan::X);
        add(opt.keys.y, Chan::Y);
        add(opt.keys.z, Chan::Z);
        add(opt.keys.feed, Chan::Feed);
        add(opt.keys.spindle, Chan::Spindle);
        add(opt.keys.block, Chan::Block);
    }

    static force_model::PredictOptions make_predict_options(const LiveOptions& o) {
        force_model::PredictOptions p;
        p.device = o.device;
        p.base_stock = o.base_stock;
        return p;
    }

    void begin_session() override { engine.begin_session(); }
    void sample(const motion_io::MotionState& s) override {
        engine.add(s, chain->block_names());
        last_sample_t_s = s.t_s;
        grid_added = true;
    }

    // Returns true when the observation ends the program.
    bool observe(const live::Observation& o, Clock::time_point arrived) {
        ++observations;
        if (!have_origin) {
            origin_ns = o.stamp_ns;
            have_origin = true;
        }
        const double t_s = double(o.stamp_ns - origin_ns) * 1e-9;
        const std::string lkey = lower(o.key);
        if (lkey.size() >= 9 && lkey.compare(lkey.size() - 9, 9, "execution") == 0) {
            if (o.value == "ACTIVE") execution_active = true;
            else if (o.value == "PROGRAM_COMPLETED") return true;
            else if (execution_active && (o.value == "READY" || o.value == "STOPPED")) return true;
            return false;
        }
        for (const auto& [key, what] : candidates) {
            if (key != o.key) continue;
            const auto [ch, priority] = what;
            std::size_t& b = best[int(ch)];
            if (priority > b) return false;   // a better key feeds this channel
            b = priority;
            if (o.value.empty() || o.value == "UNAVAILABLE") return false;   // held, as the file reader does
            LogReading r;
            r.t_s = t_s;
            r.line = observations;
            switch (ch) {
            case Chan::Pos: {
                r.channel = LogReading::Channel::Position;
                std::string_view v = o.value;
                for (int k = 0; k < 3; ++k) {
                    while (!v.empty() && v.front() == ' ') v.remove_prefix(1);
                    const std::size_t end = std::min(v.find(' '), v.size());
                    if (!parse_double(v.substr(0, end), r.value[k])) return warn(o, "3 numbers 'x y z'");
                    r.value[k] *= units.length_mm;
                    v.remove_prefix(end);
                }
                while (!v.empty() && v.front() == ' ') v.remove_prefix(1);
                if (!v.empty()) return warn(o, "3 numbers 'x y z'");
                chain->push(r);
                waiting.emplace_back(t_s, arrived);
                return false;
            }
            case Chan::X:
            case Chan::Y:
            case Chan::Z: {
                double v = 0;
                if (!parse_double(o.value, v)) return warn(o, "a number");
                chain->push_axis(int(ch) - int(Chan::X), t_s, v * units.length_mm, observations);
                waiting.emplace_back(t_s, arrived);
                return false;
            }
            case Chan::Feed:
            case Chan::Spindle: {
                double v = 0;
                if (!parse_double(o.value, v)) return warn(o, "a number");
                r.channel = ch == Chan::Feed ? LogReading::Channel::Feed : LogReading::Channel::Spindle;
                r.value[0] = v * (ch == Chan::Feed ? units.feed_mm_min : units.spindle_rpm);
                chain->push(r);
                return false;
            }
            case Chan::Block:
                r.channel = LogReading::Channel::Block;
                r.block = o.value;
                chain->push(r);
                return block_ends_program(o.value);
            }
        }
        return false;
    }

    bool warn(const live::Observation& o, const char* expected) {
        if (cb.event) {
            live::SourceEvent e;
            e.kind = live::EventKind::Warning;
            e.at = live::WallClock::now();
            e.message = fmt::format("key '{}': '{}' is not {}; skipped", o.key, o.value, expected);
            cb.event(e);
        }
        return false;
    }

    void run_engine(bool final_flush) {
        out.samples.clear();
        out.blocks.clear();
        if (!final_flush) {
            if (!grid_added) return;
            engine.advance(out);
        }
        grid_added = false;
        hand_out();
    }

    void hand_out() {
        if (!out.samples.empty()) {
            force_rows += out.samples.size();
            machine_t_s = out.samples.back().t_s;
            if (cb.samples) cb.samples(out.samples, chain->block_names());
            const auto now = Clock::now();
            double newest = -1;
            while (!waiting.empty() && waiting.front().first <= machine_t_s) {
                newest = std::chrono::duration<double>(now - waiting.front().second).count();
                lags.push_back(newest);
                waiting.pop_front();
            }
            if (cb.stored && newest >= 0) cb.stored(machine_t_s, newest);
        }
        for (const auto& b : out.blocks)
            if (cb.block) cb.block(b);
    }
};

LiveRun::LiveRun(const LiveOptions& opt, const LiveCallbacks& cb) : impl_(std::make_unique<Impl>(opt, cb)) {}
LiveRun::~LiveRun() = default;

std::optional<LiveEnd> LiveRun::push(const live::Batch& batch, Clock::time_point arrived) {
    Impl& m = *impl_;
    bool ended = false;
    for (const auto& o : batch.observations) {
        if (m.observe(o, arrived)) {
            ended = true;
            break;
        }
    }
    m.run_engine(false);
    for (const auto& e : batch.events) {
        if (e.kind == live::EventKind::Gap) {
            // Never interpolate across lost data: the held samples come out, a new session begins.
            m.chain->flush();
            m.run_engine(false);
            m.gaps.push_back({m.last_sample_t_s, e.gap_s, e.message});
        }
        if (m.cb.event) m.cb.event(e);
    }
    if (ended) return LiveEnd::ProgramEnd;
    return std::nullopt;
}

LiveResult LiveRun::finish(LiveEnd end, std::string reason) {
    Impl& m = *impl_;
    m.chain->flush();
    m.out.samples.clear();
    m.out.blocks.clear();
    LiveResult r;
    r.prediction = m.engine.finish(m.out);
    m.hand_out();
    r.end = end;
    r.end_reason = std::move(reason);
    r.motion = m.engine.motion();
    r.ingest = m.chain->report();
    r.gaps = m.gaps;
    r.lags_s = m.lags;
    r.observations = m.observations;
    r.force_rows = m.force_rows;
    r.origin_ns = m.origin_ns;
    return r;
}

const std::vector<double>& LiveRun::lags_s() const { return impl_->lags; }
std::int64_t LiveRun::origin_ns() const { return impl_->origin_ns; }
double LiveRun::machine_t_s() const { return impl_->machine_t_s; }
std::size_t LiveRun::observations() const { return impl_->observations; }
std::size_t LiveRun::motion_samples() const { return impl_->engine.motion_samples(); }

LiveResult run_live(live::Source& source, const LiveOptions& opt, const LiveCallbacks& cb, const std::atomic<bool>& stop) {
    LiveRun run(opt, cb);
    live::Batch batch;
    auto last_data = Clock::now();
    while (true) {
        if (stop) return run.finish(LiveEnd::Stopped, "stopped");
        source.next(batch, std::chrono::milliseconds(100), stop);
        const auto now = Clock::now();
        if (!batch.observations.empty()) last_data = now;
        if (auto end = run.push(batch, now)) return run.finish(*end, "program end");
        if (opt.max_motion_samples > 0 && run.motion_samples() >= opt.max_motion_samples)
            return run.finish(LiveEnd::Limit, fmt::format("the run reached its limit of {} motion samples ({:.0f} s at the {:g} ms grid)",
                                                          opt.max_motion_samples, double(opt.max_motion_samples) * opt.step_ms * 1e-3,
                                                          opt.step_ms));
        if (opt.idle_timeout.count() > 0 && now - last_data > opt.idle_timeout)
            return run.finish(LiveEnd::Idle, fmt::format("no data for {} s", opt.idle_timeout.count() / 1000.0));
    }
}

}  // namespace cutload::app
