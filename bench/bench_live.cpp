// Live-run latency (issue 16): the lag from a position reading arriving at the service to its
// force row being stored, for the demo log played by the replay adapter (live::ReplayAdapter) over
// loopback SHDR, through app::run_live, each batch of rows stored as the service stores it (one
// SQLite transaction: a packed chunk and the run's status). Prints p50 / p95 / p99 / max lag at 1x for
// a run of --minutes (the log loops; issue: 10 minutes), the p95 of each minute (does the lag
// grow?), and for each replay speed of a sweep the same figures, naming the highest speed whose
// p95 stays under 250 ms. With the load average: the machine is shared.
//
//   bench_live [--minutes M] [--sweep-s S] [--speeds 1,2,5,...] [--log FILE --spec FILE]
//              [--sampling polled|event] [--clock-batch N]
//
// By default the log is generated (motion_io::synthesize_dry_run, seeded): zig-zag facing layers
// over the demo stock (105 x 90 x 30 mm, D8 flat end mill at 6000 mm/min, ae 6 mm), as many layers
// as fill --minutes, each ap = 30 mm / (layers + 1), so every minute of the 1x run cuts material.
// With --log FILE the file loops instead (after its first pass later passes cut air).
#include "app/live_run.hpp"
#include "db/live.hpp"
#include "db/store.hpp"
#include "live/replay.hpp"
#include "motion_io/synth.hpp"
#include "server/live_runs.hpp"

#include "bench_util.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

using namespace cutload;
namespace fs = std::filesystem;

namespace {

double pct(std::vector<double> v, double p) {
    if (v.empty()) return 0;
    std::sort(v.begin(), v.end());
    const std::size_t i = std::min(v.size() - 1, std::size_t(p / 100.0 * double(v.size() - 1) + 0.5));
    return v[i];
}

struct Lap {
    std::vector<double> lags_s;
    std::size_t rows = 0;
    double simulated_s = 0, wall_s = 0;
};

Lap run(const std::string& log, const force_model::RunSpec& spec, double speed, double wall_s, db::Store& store,
        std::size_t clock_batch, bool polled) {
    live::ReplayOptions ro;
    ro.log = log;
    ro.port = 0;
    ro.speed = speed;
    ro.loop = true;
    live::ReplayAdapter adapter(ro);
    auto source = live::open_source("shdr://127.0.0.1:" + std::to_string(adapter.port()));
    std::int64_t run_id = 0;
    {
        auto s = store.session();
        db::Transaction tx(*s);
        db::NewRun nr;
        nr.inputs_json = "{\"live\":{}}";
        nr.created_at = db::now_iso();
        run_id = s->live().create(nr, "{}");
        tx.commit();
    }
    app::LiveOptions opt;
    opt.spec = spec;
    opt.polled = polled;
    opt.clock_batch_readings = clock_batch;
    opt.idle_timeout = std::chrono::milliseconds(0);
    Lap lap;
    const auto t0 = std::chrono::steady_clock::now();
    app::LiveCallbacks cb;
    cb.samples = [&](const std::vector<force_model::ForceSample>& rows, const std::vector<std::string>&) {
        const auto bytes = server::LiveRuns::pack_rows(rows);
        auto s = store.session();
        db::Transaction tx(*s);
        s->live().add_chunk(run_id, rows.front().t_s, rows.back().t_s, std::int64_t(rows.size()), bytes);
        db::LiveStatusUpdate u;
        u.connection = "connected";
        u.machine_t_s = rows.back().t_s;
        u.updated_at = db::now_iso();
        s->live().update_status(run_id, u);
        tx.commit();
        lap.rows += rows.size();
    };
    std::atomic<bool> stop{false};
    std::thread timer([&] {
        while (!stop && std::chrono::steady_clock::now() - t0 < std::chrono::duration<double>(wall_s))
            std::this_thread::sleep_for(std::chrono::milliseconds(20));
        stop = true;
    });
    const app::LiveResult r = app::run_live(*source, opt, cb, stop);
    timer.join();
    lap.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    lap.lags_s = r.lags_s;
    lap.simulated_s = r.prediction.stats.simulated_s;
    return lap;
}

// The demo's machine and client; program in machine coordinates (work zero as the demo's).
std::string generate_facing_log(double minutes, const fs::path& path) {
    const double work_zero[3] = {200, -300, -350};
    const double feed_mm_min = 6000, ae_mm = 6, stock_x_mm = 105, stock_y_mm = 90, stock_z_mm = 30, safe_z_mm = 40;
    const int passes = int(std::ceil((stock_y_mm - 2) / ae_mm)) + 1;
    const double layer_s = passes * (stock_x_mm + 8 + ae_mm) / feed_mm_min * 60 + 2;   // cuts, step-overs, retract
    const int layers = std::max(1, int(std::ceil(minutes * 60 / layer_s)));
    const double ap_mm = stock_z_mm / (layers + 1);
    motion_io::DryRunSpec spec = motion_io::demo_dry_run_spec();
    spec.program.clear();
    int n = 10;
    auto add = [&](bool rapid, double x, double y, double z) {
        motion_io::ProgramBlock b;
        b.name = "N" + std::to_string(n);
        n += 10;
        b.rapid = rapid;
        b.target_mm[0] = work_zero[0] + x;
        b.target_mm[1] = work_zero[1] + y;
        b.target_mm[2] = work_zero[2] + z;
        b.feed_mm_min = rapid ? 0 : feed_mm_min;
        spec.program.push_back(b);
    };
    for (int layer = 1; layer <= layers; ++layer) {
        const double z = stock_z_mm - layer * ap_mm;
        add(true, -5, 1, safe_z_mm);
        add(true, -5, 1, z);
        for (int k = 0; k < passes; ++k) {
            const double y = std::min(stock_y_mm - 1, 1 + k * ae_mm);
            const double x_end = k % 2 == 0 ? stock_x_mm + 5 : -5;
            if (k > 0) add(false, k % 2 == 0 ? -5 : stock_x_mm + 5, y, z);   // step over outside the stock
            add(false, x_end, y, z);
        }
        add(true, spec.program.back().target_mm[0] - work_zero[0], spec.program.back().target_mm[1] - work_zero[1], safe_z_mm);
    }
    std::ofstream out(path);
    motion_io::synthesize_dry_run(spec, out);
    return path.string();
}

void print_lap(const char* label, const Lap& l) {
    std::printf("%-14s wall %6.1f s  machine %7.1f s  rows %9zu  readings %8zu  lag p50 %6.1f ms  p95 %6.1f ms  p99 %6.1f ms  "
                "max %7.1f ms  load %s\n",
                label, l.wall_s, l.simulated_s, l.rows, l.lags_s.size(), 1e3 * pct(l.lags_s, 50), 1e3 * pct(l.lags_s, 95),
                1e3 * pct(l.lags_s, 99), 1e3 * pct(l.lags_s, 100), bench::load_average().c_str());
}

}  // namespace

int main(int argc, char** argv) {
    double minutes = 10, sweep_s = 15;
    std::size_t clock_batch = 64;   // the service's default for polled sources
    bool polled = true;             // a CSV log replayed re-sends every reading
    std::string log;   // empty: generated
    std::string spec_path = std::string(CUTLOAD_SOURCE_DIR) + "/data/demo_run.json";
    std::vector<double> speeds{1, 2, 5, 10, 20, 50};
    for (int i = 1; i + 1 < argc; i += 2) {
        const std::string a = argv[i], v = argv[i + 1];
        if (a == "--minutes") minutes = std::stod(v);
        else if (a == "--sweep-s") sweep_s = std::stod(v);
        else if (a == "--log") log = v;
        else if (a == "--clock-batch") clock_batch = std::size_t(std::stoul(v));
        else if (a == "--sampling") polled = v == "polled";
        else if (a == "--spec") spec_path = v;
        else if (a == "--speeds") {
            speeds.clear();
            std::stringstream ss(v);
            for (std::string x; std::getline(ss, x, ',');) speeds.push_back(std::stod(x));
        } else {
            std::fprintf(stderr, "bench_live: unknown option %s\n", a.c_str());
            return 2;
        }
    }
    const force_model::RunSpec spec = force_model::load_run_spec(spec_path);
    const fs::path dir = fs::temp_directory_path() / ("bench_live_" + std::to_string(::getpid()));
    fs::create_directories(dir);
    if (log.empty()) log = generate_facing_log(minutes, dir / "facing_dryrun.csv");
    auto store = db::Store::open((dir / "bench.db").string());
    store->migrate();
    std::printf("bench_live: %s, %s sampling (clock batch %zu), CPU engine, lag = reading arrival -> its force row "
                "committed to SQLite\n", log.c_str(), polled ? "polled" : "event", clock_batch);

    // 1x for `minutes`, with the p95 of each minute.
    const Lap slow = run(log, spec, 1.0, minutes * 60, *store, clock_batch, polled);
    print_lap("1x", slow);
    // Per-minute p95: lags are in arrival order, and at 1x arrivals are spread evenly over the run.
    const std::size_t per_min = std::max<std::size_t>(1, std::size_t(double(slow.lags_s.size()) / std::max(1.0, minutes)));
    std::printf("1x p95 by minute (ms):");
    for (std::size_t i = 0; i < slow.lags_s.size(); i += per_min) {
        const std::vector<double> part(slow.lags_s.begin() + std::ptrdiff_t(i),
                                       slow.lags_s.begin() + std::ptrdiff_t(std::min(slow.lags_s.size(), i + per_min)));
        std::printf(" %.1f", 1e3 * pct(part, 95));
    }
    std::printf("\n");

    double best = 0;
    for (double speed : speeds) {
        const Lap l = run(log, spec, speed, sweep_s, *store, clock_batch, polled);
        char label[32];
        std::snprintf(label, sizeof label, "%gx", speed);
        print_lap(label, l);
        if (pct(l.lags_s, 95) < 0.25) best = std::max(best, speed);
    }
    std::printf("highest replay speed with p95 lag < 250 ms: %gx (of those tried)\n", best);
    fs::remove_all(dir);
    return 0;
}
