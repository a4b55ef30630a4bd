#include "live_runs.hpp"
#include "results.hpp"

#include "db/live.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cstring>

namespace cutload::server {

namespace {

constexpr std::size_t kRowBytes = 8 + 6 * 4 + 4;

json gap_json(const app::LiveGap& g) { return {{"t_s", g.t_s}, {"gap_s", g.gap_s}, {"message", g.message}}; }

force_model::BlockSummary block_from_json(const json& j) {
    force_model::BlockSummary b;
    b.block = j.at("block").get<std::string>();
    b.t_start_s = j.at("t_start_s").get<double>();
    b.t_end_s = j.at("t_end_s").get<double>();
    b.peak_force_N = j.at("peak_force_N").get<double>();
    b.mean_force_N = j.at("mean_force_N").get<double>();
    b.peak_torque_Nm = j.at("peak_torque_Nm").get<double>();
    b.peak_power_kW = j.at("peak_power_kW").get<double>();
    b.max_chip_mm = j.at("max_chip_mm").get<double>();
    b.max_bending_MPa = j.at("max_bending_MPa").get<double>();
    b.max_radial_engagement_mm = j.at("max_radial_engagement_mm").get<double>();
    b.max_axial_engagement_mm = j.at("max_axial_engagement_mm").get<double>();
    b.removed_mm3 = j.at("removed_mm3").get<double>();
    for (const auto& f : j.at("flags"))
        b.flags.push_back({f.at("flag").get<std::string>(), f.at("t_s").get<double>(), f.at("value").get<double>()});
    return b;
}

}  // namespace

struct LiveRuns::Worker {
    std::int64_t run_id = 0;
    std::string source;
    app::LiveOptions opt;
    std::atomic<bool> stop{false};
    std::thread thread;
    std::mutex mu;            // guards the status below
    LiveState status;
};

std::vector<unsigned char> LiveRuns::pack_rows(const std::vector<force_model::ForceSample>& rows) {
    std::vector<unsigned char> out(rows.size() * kRowBytes);
    unsigned char* p = out.data();
    for (const auto& r : rows) {
        const float f[6] = {r.fx_N, r.fy_N, r.fz_N, r.torque_Nm, r.power_kW, r.chip_mm};
        std::memcpy(p, &r.t_s, 8);
        std::memcpy(p + 8, f, sizeof f);
        std::memcpy(p + 8 + sizeof f, &r.block, 4);
        p += kRowBytes;
    }
    return out;
}

std::vector<force_model::ForceSample> LiveRuns::unpack_rows(std::span<const unsigned char> data) {
    std::vector<force_model::ForceSample> out(data.size() / kRowBytes);
    const unsigned char* p = data.data();
    for (auto& r : out) {
        float f[6];
        std::memcpy(&r.t_s, p, 8);
        std::memcpy(f, p + 8, sizeof f);
        std::memcpy(&r.block, p + 8 + sizeof f, 4);
        r.fx_N = f[0], r.fy_N = f[1], r.fz_N = f[2], r.torque_Nm = f[3], r.power_kW = f[4], r.chip_mm = f[5];
        p += kRowBytes;
    }
    return out;
}

LiveRuns::LiveRuns(db::Store& store, const ServerOptions& opt, std::function<void()> on_alerts)
    : store_(store), opt_(opt), on_alerts_(std::move(on_alerts)) {}

LiveRuns::~LiveRuns() { stop_all(); }

std::int64_t LiveRuns::start(const db::NewRun& run, const json& source_json, const std::string& source,
                             app::LiveOptions opt) {
    auto w = std::make_shared<Worker>();
    w->source = source;
    w->opt = std::move(opt);
    w->status.open = true;
    w->status.connection = "connecting";
    {
        auto s = store_.session();
        db::Transaction tx(*s);
        w->run_id = s->live().create(run, source_json.dump());
        tx.commit();
    }
    std::lock_guard lock(mu_);
    workers_[w->run_id] = w;
    w->thread = std::thread([this, w] { run_worker(w); });
    return w->run_id;
}

bool LiveRuns::stop(std::int64_t run_id) {
    std::lock_guard lock(mu_);
    auto it = workers_.find(run_id);
    if (it == workers_.end()) return false;
    {
        std::lock_guard wl(it->second->mu);
        if (!it->second->status.open) return false;
    }
    it->second->stop = true;
    return true;
}

void LiveRuns::stop_all() {
    std::map<std::int64_t, std::shared_ptr<Worker>> all;
    {
        std::lock_guard lock(mu_);
        for (auto& [id, w] : workers_) w->stop = true;
        all = workers_;
    }
    for (auto& [id, w] : all)
        if (w->thread.joinable()) w->thread.join();
    std::lock_guard lock(mu_);
    for (auto& [id, w] : all) workers_.erase(id);
}

std::optional<LiveState> LiveRuns::state(std::int64_t run_id) {
    {
        std::lock_guard lock(mu_);
        if (auto it = workers_.find(run_id); it != workers_.end()) {
            std::lock_guard wl(it->second->mu);
            if (it->second->status.open) return it->second->status;
        }
    }
    auto s = store_.session();
    const auto rec = s->live().get(run_id);
    if (!rec) return std::nullopt;
    LiveState st;
    st.open = rec->open;
    st.connection = rec->connection;
    st.lag_ms = rec->lag_ms;
    st.machine_t_s = rec->machine_t_s;
    st.rows = rec->rows;
    st.alerts = rec->alerts;
    st.gaps = json::parse(rec->gaps_json);
    st.end_reason = rec->end_reason;
    return st;
}

void LiveRuns::run_worker(std::shared_ptr<Worker> w) {
    const std::int64_t id = w->run_id;
    std::vector<force_model::ForceSample> all_rows;   // for the stored run at the close (as an offline run holds them)
    std::int64_t block_idx = 0;
    json block_names = json::array();
    auto status_update = [&](db::Session& s) {
        db::LiveStatusUpdate u;
        {
            std::lock_guard lock(w->mu);
            u.connection = w->status.connection;
            u.lag_ms = w->status.lag_ms;
            u.machine_t_s = w->status.machine_t_s;
            u.rows = w->status.rows;
            u.alerts = w->status.alerts;
            u.gaps_json = w->status.gaps.dump();
        }
        u.block_names_json = block_names.dump();
        u.updated_at = db::now_iso();
        s.live().update_status(id, u);
    };
    app::LiveCallbacks cb;
    cb.samples = [&](const std::vector<force_model::ForceSample>& rows, const std::vector<std::string>& names) {
        all_rows.insert(all_rows.end(), rows.begin(), rows.end());
        if (block_names.size() != names.size()) block_names = names;
        const auto bytes = pack_rows(rows);
        {
            std::lock_guard lock(w->mu);
            w->status.rows += std::int64_t(rows.size());
            w->status.machine_t_s = rows.back().t_s;
        }
        auto s = store_.session();
        db::Transaction tx(*s);
        s->live().add_chunk(id, rows.front().t_s, rows.back().t_s, std::int64_t(rows.size()), bytes);
        status_update(*s);
        tx.commit();
    };
    cb.stored = [&](double, double lag_s) {
        std::lock_guard lock(w->mu);
        w->status.lag_ms = lag_s * 1e3;
    };
    cb.block = [&](const force_model::BlockSummary& b) {
        force_model::Prediction one;
        one.blocks.push_back(b);
        int raised = 0;
        {
            auto s = store_.session();
            db::Transaction tx(*s);
            s->live().add_block(id, block_idx, block_summary_json(std::size_t(block_idx), b).dump(), !b.flags.empty());
            raised = raise_alerts(*s, id, one, opt_.limit_alerts);
            {
                std::lock_guard lock(w->mu);
                w->status.alerts += raised;
            }
            status_update(*s);
            tx.commit();
        }
        ++block_idx;
        if (raised > 0 && on_alerts_) on_alerts_();
    };
    cb.event = [&](const live::SourceEvent& e) {
        bool changed = true;
        {
            std::lock_guard lock(w->mu);
            switch (e.kind) {
            case live::EventKind::Connected: w->status.connection = "connected"; break;
            case live::EventKind::Disconnected:
            case live::EventKind::ConnectFailed: w->status.connection = "disconnected"; break;
            case live::EventKind::Gap:
                w->status.gaps.push_back({{"t_s", w->status.machine_t_s}, {"gap_s", e.gap_s}, {"message", e.message}});
                break;
            default: changed = false;
            }
        }
        if (e.kind != live::EventKind::Warning) spdlog::info("live run {}: {} {}", id, live::to_string(e.kind), e.message);
        if (!changed) return;
        auto s = store_.session();
        db::Transaction tx(*s);
        status_update(*s);
        tx.commit();
    };

    try {
        auto source = live::open_source(w->source);
        app::LiveResult r = app::run_live(*source, w->opt, cb, w->stop);
        force_model::Prediction p = std::move(r.prediction);
        p.samples = std::move(all_rows);
        json gaps = json::array();
        for (const auto& g : r.gaps) gaps.push_back(gap_json(g));
        std::int64_t alerts = 0;
        {
            std::lock_guard lock(w->mu);
            alerts = w->status.alerts;
        }
        const json live{{"source", w->source},
                        {"end", app::to_string(r.end)},
                        {"end_reason", r.end_reason},
                        {"gaps", gaps},
                        {"observations", r.observations},
                        {"origin_ns", r.origin_ns}};
        auto s = store_.session();
        db::Transaction tx(*s);
        store_live_result(*s, id, r.motion, p, int(alerts), live);
        s->live().close(id, app::to_string(r.end), db::now_iso());
        tx.commit();
        spdlog::info("live run {} closed: {} ({} rows, {} blocks)", id, r.end_reason, r.force_rows, p.blocks.size());
    } catch (const std::exception& e) {
        spdlog::error("live run {} failed: {}", id, e.what());
        try {
            auto s = store_.session();
            db::Transaction tx(*s);
            s->jobs().finish(db::kRunQueue, id, db::JobState::Failed, std::string(e.what()), db::now_iso(), std::nullopt);
            s->live().close(id, "failed", db::now_iso());
            tx.commit();
        } catch (const std::exception& e2) {
            spdlog::error("live run {}: cannot mark it failed: {}", id, e2.what());
        }
    }
    {
        std::lock_guard lock(w->mu);
        w->status.open = false;
        w->status.connection = "closed";
    }
    // The worker stays in the map (its thread is joined by stop_all); state() reads the store once
    // it is closed.
}

void LiveRuns::close_stored(std::int64_t run_id, const std::string& reason) {
    auto s = store_.session();
    db::Transaction tx(*s);
    const auto rec = s->live().get(run_id);
    if (!rec || !rec->open) return;
    force_model::Prediction p;
    p.block_names = json::parse(rec->block_names_json).get<std::vector<std::string>>();
    for (std::int64_t after = 0;;) {
        const auto chunks = s->live().chunks(run_id, after, 256);
        if (chunks.empty()) break;
        for (const auto& c : chunks) {
            const auto rows = unpack_rows(c.data);
            p.samples.insert(p.samples.end(), rows.begin(), rows.end());
            after = c.seq;
        }
    }
    // A block the program ran again was stored again, its summary then covering both stretches:
    // the later one stands, in the place of the first.
    for (const auto& b : s->live().blocks(run_id, 0)) {
        force_model::BlockSummary summary = block_from_json(json::parse(b.body_json));
        auto same = std::find_if(p.blocks.begin(), p.blocks.end(), [&](const auto& x) { return x.block == summary.block; });
        if (same == p.blocks.end()) p.blocks.push_back(std::move(summary));
        else *same = std::move(summary);
    }
    json gaps = json::parse(rec->gaps_json);
    gaps.push_back({{"t_s", rec->machine_t_s}, {"gap_s", nullptr}, {"message", reason}});
    const json live{{"source", json::parse(rec->source_json).value("source", "")},
                    {"end", "service_restart"},
                    {"end_reason", reason},
                    {"gaps", gaps}};
    motion_io::MotionModel no_motion;   // the grid was in the lost process's memory only
    store_live_result(*s, run_id, no_motion, p, int(rec->alerts), live);
    s->live().close(run_id, "service_restart", db::now_iso());
    tx.commit();
}

int LiveRuns::recover() {
    std::vector<std::int64_t> open;
    {
        auto s = store_.session();
        open = s->live().open_runs();
    }
    for (auto id : open) {
        try {
            close_stored(id, "the service stopped during the live run: closed with what was stored before");
            spdlog::warn("live run {} was left open by a previous process: closed with what was stored", id);
        } catch (const std::exception& e) {
            spdlog::error("live run {}: cannot close it: {}", id, e.what());
        }
    }
    return int(open.size());
}

}  // namespace cutload::server
