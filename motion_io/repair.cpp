#include "repair.hpp"

#include "motion_io/hermite.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace cutload::motion_io::detail {
namespace {

constexpr std::size_t kBatch = 1024;          // readings timed per batch (bounded memory)
constexpr std::size_t kPhaseChunk = 64;       // readings per phase estimate (follows clock drift)
constexpr std::size_t kCalibrationMaxWait = 16384;  // readings held while waiting for motion
constexpr std::size_t kCalibrationReads = 2048;
constexpr std::size_t kMinMovingPairs = 40;

bool same_position(const PosRead& a, const PosRead& b) {
    return a.p_mm[0] == b.p_mm[0] && a.p_mm[1] == b.p_mm[1] && a.p_mm[2] == b.p_mm[2];
}

double distance(const double a[3], const double b[3]) {
    return std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
}

std::size_t moving_pairs(const std::vector<PosRead>& r, std::size_t begin, std::size_t end) {
    std::size_t c = 0;
    for (std::size_t k = begin + 1; k < end; ++k) c += !same_position(r[k - 1], r[k]);
    return c;
}

}  // namespace

void Repairer::ChannelStats::add(double t_s) {
    ++samples;
    if (have_last && t_s >= last_t) intervals.add(t_s - last_t);
    have_last = true;
    last_t = t_s;
}

Repairer::Repairer(Diagnostics& diag, GridSink& out, double step_s, bool event_driven)
    : diag_(diag), out_(out), step_s_(step_s), event_driven_(event_driven) {}

void Repairer::begin_session() {
    prev2_.reset(), prev1_.reset(), held_.reset();
    pending_.clear();
    period_s_ = phase_s_ = ref_phase_s_ = 0;
    have_ref_phase_ = false;
    calibration_attempts_ = 0;
    last_committed_.reset();
    knots_.clear();
    next_knot_ = 0;
    prev_hermite_.reset();
    have_grid_ = false;
    grid_i_ = 0;
    have_prev_sample_ = false;
    angle_deg_ = 0;
    spindle_.clear();
    blocks_.clear();
    current_block_ = -1;
    tools_.clear();
    current_tool_ = -1;
    session_pos_reads_ = 0;
    last_raw_.reset();
    last_feed_.reset();
    usual_dt_ = 0;
    for (ChannelStats* c : {&pos_stats_, &feed_stats_, &spindle_stats_, &block_stats_, &tool_stats_}) c->have_last = false;
    ++sessions_;
    out_.begin_session();
}

void Repairer::record(const Record& r) {
    switch (r.ch) {
        case Chan::Pos:
            on_pos(r);
            break;
        case Chan::Feed:
            feed_stats_.add(r.t_s);
            if (last_feed_) feed_integral_mm_ += last_feed_->second / 60.0 * (r.t_s - last_feed_->first);
            last_feed_ = {r.t_s, r.v[0]};
            break;
        case Chan::Spindle:
            spindle_stats_.add(r.t_s);
            spindle_.emplace_back(r.t_s, r.v[0]);
            break;
        case Chan::Block:
            block_stats_.add(r.t_s);
            blocks_.emplace_back(r.t_s, r.block);
            break;
        case Chan::Tool:
            tool_stats_.add(r.t_s);
            tools_.emplace_back(r.t_s, static_cast<std::int32_t>(r.v[0]));
            break;
        default:
            break;
    }
}

void Repairer::on_pos(const Record& r) {
    PosRead read;
    read.t_s = r.t_s;
    std::copy(r.v, r.v + 3, read.p_mm);
    pos_stats_.add(r.t_s);
    ++pos_reads_total_;
    if (session_pos_reads_++ == 0) {
        session_first_t_ = r.t_s;
        session_first_line_ = r.line;
    }
    session_last_t_ = r.t_s;

    if (last_raw_) {
        const double dt = r.t_s - last_raw_->t_s;
        const double d = distance(read.p_mm, last_raw_->p_mm);
        path_length_mm_ += d;
        if (dt > 0) {
            // What plain differencing of consecutive readings would call the feed.
            const double f = d / dt * 60.0;
            raw_min_ = have_raw_feed_ ? std::min(raw_min_, f) : f;
            raw_max_ = have_raw_feed_ ? std::max(raw_max_, f) : f;
            have_raw_feed_ = true;
        }
        if (!event_driven_ && dt > 0) {
            // The usual interval follows the log slowly; a gap does not enter it.
            if (usual_dt_ > 0 && dt > 10 * usual_dt_ && dt > 0.05)
                diag_.warn("gap", r.line, fmt::format("no position reading for {:.3f} s (usual interval {:.4f} s); "
                                                      "interpolated across", dt, usual_dt_));
            else
                usual_dt_ = usual_dt_ > 0 ? 0.95 * usual_dt_ + 0.05 * dt : dt;
        }
    }
    last_raw_ = read;
    if (event_driven_) {
        accept_read(read);  // an event-driven log only sends changes: no stale repeats to drop
    } else {
        stale_filter(read, r.line);
    }
}

// A reading identical to the previous one while the machine moves means the CNC had not
// latched a new position since the last read: it carries no new sample. At standstill repeats
// are genuine and kept.
void Repairer::stale_filter(const PosRead& read, std::size_t line) {
    if (held_) {
        const bool repeat = prev1_ && same_position(*held_, *prev1_);
        const bool moving = (prev1_ && prev2_ && !same_position(*prev1_, *prev2_)) || !same_position(read, *held_);
        if (repeat && moving) {
            ++stale_dropped_;
            diag_.warn("stale_repeat", held_line_, "position read again before the CNC updated it; dropped");
        } else {
            accept_read(*held_);
        }
        prev2_ = prev1_;
        prev1_ = held_;
    }
    held_ = read;
    held_line_ = line;
}

void Repairer::accept_read(const PosRead& read) {
    pending_.push_back(read);
    if (pending_.size() >= kBatch) process_batch(false);
}

void Repairer::process_batch(bool final) {
    if (pending_.empty()) return;
    if (period_s_ == 0 && calibration_attempts_ < 3 && !event_driven_) {
        const std::size_t pairs = moving_pairs(pending_, 0, pending_.size());
        if (pairs < kMinMovingPairs && !final && pending_.size() < kCalibrationMaxWait) return;
        // A session that ends before the streaming wait is over still gets its grid from the
        // little it has.
        if (pairs >= kMinMovingPairs || (final && pairs >= kMinPeriodPairs)) {
            ++calibration_attempts_;
            // Calibrate on the moving stretch, starting one reading before its first move.
            std::size_t first = 1;
            while (first < pending_.size() && same_position(pending_[first - 1], pending_[first])) ++first;
            const std::size_t begin = first - 1, end = std::min(pending_.size(), begin + kCalibrationReads);
            const UpdatePeriod found = estimate_update_period(
                std::vector<PosRead>(pending_.begin() + static_cast<long>(begin), pending_.begin() + static_cast<long>(end)));
            period_s_ = found.period_s;
            if (period_s_ > 0 && found.nominal) warn_short_stretch(found, end - begin);
        }
    }
    // The last reading stays for the next batch: timing a reading looks at its successor.
    const std::size_t commit = final ? pending_.size() : pending_.size() - 1;
    std::vector<PosRead> chunk;
    chunk.reserve(kPhaseChunk + 1);
    for (std::size_t s = 0; s < commit; s += kPhaseChunk) {
        const std::size_t e = std::min(commit, s + kPhaseChunk);
        double ref_before = ref_phase_s_, ref_step = 0;
        if (period_s_ > 0) {
            chunk.clear();
            if (last_committed_) chunk.push_back(*last_committed_);
            chunk.insert(chunk.end(), pending_.begin() + static_cast<long>(s), pending_.begin() + static_cast<long>(e));
            phase_s_ = best_phase(chunk.data(), chunk.size(), period_s_, phase_s_);
            if (!have_ref_phase_) ref_before = phase_s_;
            follow_phase();
            ref_step = wrap_half_period(ref_phase_s_ - ref_before);
        }
        // The chunk's phase picks each reading's tick; its time is put on the reference grid,
        // which follows the chunk phases slowly and is moved gradually across the chunk, so
        // neither phase noise nor clock drift jolts the velocity.
        const double shift = period_s_ > 0 ? wrap_half_period(ref_before - phase_s_) : 0.0;
        for (std::size_t k = s; k < e; ++k) {
            const double ramp = ref_step * static_cast<double>(k - s + 1) / static_cast<double>(e - s);
            add_knot(tick_of(k) + shift + ramp, pending_[k].p_mm);
            last_committed_ = pending_[k];
        }
    }
    pending_.erase(pending_.begin(), pending_.begin() + static_cast<long>(commit));
}

// Too few readings to measure the period by its phase drift: say what the time stamps allowed
// and what was taken, so a user can judge a feed that rests on it.
void Repairer::warn_short_stretch(const UpdatePeriod& found, std::size_t reads) {
    diag_.warn("period_short_log", session_first_line_,
               fmt::format("CNC update period from {} position readings only (too few to measure its drift): the "
                           "time stamps allow {:.3f} to {:.3f} ms; the nominal {:.3f} ms inside it taken",
                           reads, found.min_s * 1e3, found.max_s * 1e3, found.period_s * 1e3));
}

double Repairer::wrap_half_period(double d) const { return d - period_s_ * std::round(d / period_s_); }

void Repairer::follow_phase() {
    if (!have_ref_phase_) {
        ref_phase_s_ = phase_s_;
        have_ref_phase_ = true;
        return;
    }
    ref_phase_s_ += 0.1 * wrap_half_period(phase_s_ - ref_phase_s_);
}

// The tick a reading shows. Close to a tick of the estimated grid, time-stamp jitter alone
// cannot tell whether the CNC had already latched; the neighbours decide: the candidate tick
// at which the reading lies on the line between its neighbours wins.
double Repairer::tick_of(std::size_t k) const {
    const PosRead& r = pending_[k];
    const double g = tick_at_or_before(r.t_s, period_s_, phase_s_);
    if (period_s_ <= 0 || knots_.empty() || k + 1 >= pending_.size()) return g;
    const double frac = (r.t_s - g) / period_s_;
    if (frac > 0.25 && frac < 0.75) return g;
    const double alt = frac <= 0.25 ? g - period_s_ : g + period_s_;
    const Knot& a = knots_.back();
    const PosRead& b = pending_[k + 1];
    const double gb = tick_at_or_before(b.t_s, period_s_, phase_s_);
    if (!(a.t_s < alt && alt < gb) || !(a.t_s < g && g < gb)) return g;
    auto miss = [&](double c) {
        const double u = (c - a.t_s) / (gb - a.t_s);
        double m2 = 0;
        for (int ax = 0; ax < 3; ++ax) {
            const double d = r.p_mm[ax] - (a.p[ax] + (b.p_mm[ax] - a.p[ax]) * u);
            m2 += d * d;
        }
        return m2;
    };
    return miss(alt) < miss(g) ? alt : g;
}

void Repairer::add_knot(double t_s, const double p[3]) {
    if (!knots_.empty()) {
        Knot& last = knots_.back();
        if (t_s <= last.t_s) {
            if (last.p[0] == p[0] && last.p[1] == p[1] && last.p[2] == p[2]) return;  // same tick read twice
            if (period_s_ > 0) {
                // Two positions on one tick: the later reading saw the next update.
                t_s = last.t_s + period_s_;
            } else {
                diag_.warn("duplicate_time", 0, "two different positions with the same time stamp; the later kept");
                std::copy(p, p + 3, last.p);
                return;
            }
        }
    }
    Knot k;
    k.t_s = t_s;
    std::copy(p, p + 3, k.p);
    knots_.push_back(k);
    finalise_velocities(false);
}

// Velocity at a knot: least-squares slope over the knots within +-half_window_s of it, and at
// least its two neighbours. With readings timed at their ticks this is exact for constant feed;
// the window of a few CNC periods averages position quantisation, as eqs. 4.1/4.2 average over
// three CNC periods.
void Repairer::finalise_velocities(bool final) {
    const double H = period_s_ > 0 ? 2 * period_s_ : 0.0;
    while (next_knot_ < knots_.size()) {
        const double tj = knots_[next_knot_].t_s;
        const bool have_right = knots_.size() > next_knot_ + 1 && knots_.back().t_s >= tj + H;
        if (!final && !have_right) break;
        std::size_t lo = next_knot_, hi = next_knot_;
        while (lo > 0 && (knots_[lo - 1].t_s >= tj - H || lo == next_knot_)) --lo;
        while (hi + 1 < knots_.size() && (knots_[hi + 1].t_s <= tj + H || hi == next_knot_)) ++hi;
        if (hi > lo) {
            double mt = 0, mp[3] = {0, 0, 0};
            for (std::size_t i = lo; i <= hi; ++i) {
                mt += knots_[i].t_s;
                for (int a = 0; a < 3; ++a) mp[a] += knots_[i].p[a];
            }
            const double n = static_cast<double>(hi - lo + 1);
            mt /= n;
            double sxx = 0, sxy[3] = {0, 0, 0};
            for (std::size_t i = lo; i <= hi; ++i) {
                const double dt = knots_[i].t_s - mt;
                sxx += dt * dt;
                for (int a = 0; a < 3; ++a) sxy[a] += dt * (knots_[i].p[a] - mp[a] / n);
            }
            for (int a = 0; a < 3; ++a) knots_[next_knot_].v[a] = sxx > 0 ? sxy[a] / sxx : 0.0;
        }
        push_hermite_knot(knots_[next_knot_], final && next_knot_ + 1 == knots_.size());
        ++next_knot_;
        // Keep the left neighbour and everything inside the next knot's window.
        while (next_knot_ >= 2 && next_knot_ < knots_.size() && knots_[0].t_s < knots_[next_knot_].t_s - H) {
            knots_.pop_front();
            --next_knot_;
        }
    }
}

void Repairer::push_hermite_knot(const Knot& k, bool last) {
    if (prev_hermite_) emit_until(*prev_hermite_, k, last);
    prev_hermite_ = k;
}

void Repairer::emit_until(const Knot& a, const Knot& b, bool include_end) {
    if (!have_grid_) {
        grid_t0_ = a.t_s;
        grid_i_ = 0;
        have_grid_ = true;
    }
    const double h = b.t_s - a.t_s;
    while (true) {
        const double t = grid_t0_ + static_cast<double>(grid_i_) * step_s_;
        if (!(t < b.t_s || (include_end && t <= b.t_s + 1e-12))) break;
        ++grid_i_;
        const double u = std::clamp((t - a.t_s) / h, 0.0, 1.0);
        GridSample s;
        s.t_s = t;
        double speed2 = 0;
        for (int ax = 0; ax < 3; ++ax) {
            const HermiteSegment seg{a.p[ax], a.v[ax], b.p[ax], b.v[ax], h};
            s.p_mm[ax] = seg.position(u);
            s.v_mm_s[ax] = seg.velocity(u);
            speed2 += s.v_mm_s[ax] * s.v_mm_s[ax];
        }
        s.spindle_rpm = spindle_rpm_at(t);
        // Trapezoid rule: exact for the linear speed that sample_between() assumes.
        if (have_prev_sample_) angle_deg_ += 6.0 * 0.5 * (prev_rpm_ + s.spindle_rpm) * step_s_;
        have_prev_sample_ = true;
        prev_rpm_ = s.spindle_rpm;
        s.spindle_angle_deg = angle_deg_;
        s.block = block_at(t);
        s.tool = tool_at(t);
        const double f = std::sqrt(speed2) * 60.0;
        rep_min_ = have_rep_feed_ ? std::min(rep_min_, f) : f;
        rep_max_ = have_rep_feed_ ? std::max(rep_max_, f) : f;
        if (!have_rep_feed_) first_position_mm_ = {s.p_mm[0], s.p_mm[1], s.p_mm[2]};
        have_rep_feed_ = true;
        out_.sample(s);
    }
}

double Repairer::spindle_rpm_at(double t_s) {
    while (spindle_.size() >= 2 && spindle_[1].first <= t_s) spindle_.pop_front();
    if (spindle_.empty()) return 0;
    const auto& [t0, r0] = spindle_[0];
    if (spindle_.size() == 1 || t_s <= t0) return r0;
    const auto& [t1, r1] = spindle_[1];
    return t1 > t0 ? r0 + (r1 - r0) * (t_s - t0) / (t1 - t0) : r1;
}

std::int32_t Repairer::block_at(double t_s) {
    // Before the first block reading, the block first read was already running.
    if (current_block_ < 0 && !blocks_.empty()) current_block_ = blocks_.front().second;
    while (!blocks_.empty() && blocks_.front().first <= t_s) {
        current_block_ = blocks_.front().second;
        blocks_.pop_front();
    }
    return current_block_;
}

std::int32_t Repairer::tool_at(double t_s) {
    // As blocks: before the first reading, the tool first read was already in the spindle.
    if (current_tool_ < 0 && !tools_.empty()) current_tool_ = tools_.front().second;
    while (!tools_.empty() && tools_.front().first <= t_s) {
        current_tool_ = tools_.front().second;
        tools_.pop_front();
    }
    return current_tool_;
}

void Repairer::end_session() {
    if (held_) {
        const bool repeat = prev1_ && same_position(*held_, *prev1_);
        const bool moving = prev1_ && prev2_ && !same_position(*prev1_, *prev2_);
        if (repeat && moving) {
            ++stale_dropped_;
            diag_.warn("stale_repeat", held_line_, "position read again before the CNC updated it; dropped");
        } else {
            accept_read(*held_);
        }
        held_.reset();
    }
    process_batch(true);
    if (session_pos_reads_ >= 2 && session_last_t_ == session_first_t_)
        diag_.fail(session_first_line_, fmt::format("time never advances: {} position samples all at t = {} s",
                                                    session_pos_reads_, session_first_t_));
    finalise_velocities(true);
    if (session_pos_reads_ > 0 && !have_grid_)
        diag_.warn("session_too_short", session_first_line_, "session without motion to resample (a single position)");
    knots_.clear();
    duration_s_ += session_last_t_ - session_first_t_;
    if (session_pos_reads_ > best_period_reads_) {
        best_period_reads_ = session_pos_reads_;
        best_period_s_ = period_s_;
    }
}

void Repairer::fill_report(IngestReport& report) const {
    report.sessions = sessions_;
    report.duration_s = duration_s_;
    auto channel = [](const ChannelStats& c) {
        ChannelReport r;
        r.samples = c.samples;
        r.interval = c.intervals.stats();
        return r;
    };
    ChannelReport pos = channel(pos_stats_);
    pos.update_period_s = best_period_s_;
    pos.stale_dropped = stale_dropped_;
    report.channels["pos"] = pos;
    if (feed_stats_.samples) report.channels["feed"] = channel(feed_stats_);
    if (spindle_stats_.samples) report.channels["spindle"] = channel(spindle_stats_);
    if (block_stats_.samples) report.channels["block"] = channel(block_stats_);
    if (tool_stats_.samples) report.channels["tool"] = channel(tool_stats_);
    report.feed_raw_min_mm_min = raw_min_;
    report.feed_raw_max_mm_min = raw_max_;
    report.feed_repaired_min_mm_min = rep_min_;
    report.feed_repaired_max_mm_min = rep_max_;
    if (have_rep_feed_) report.first_position_mm = first_position_mm_;
}

double Repairer::feed_to_path_ratio() const {
    if (feed_stats_.samples < 10 || path_length_mm_ < 1.0 || feed_integral_mm_ <= 0) return 0;
    return feed_integral_mm_ / path_length_mm_;
}

}  // namespace cutload::motion_io::detail
