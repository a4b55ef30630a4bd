// An hour-long program end to end (issue 14): a generated roughing log of zig-zag pocket layers
// (ae 1 mm, ap 3 mm, F6000, S10000 M03, the demo's D8 two-flute end mill in Al7075) predicted by the
// built `cutload predict` binary as a user runs it (process start, ingest, engine, FORCES.csv
// streamed to disk). Prints the log's size, the wall time, the real-time factor, the child's CPU
// time and peak resident memory (wait4's ru_maxrss) and the bytes written, with the load average
// before and after (the machine is shared).
//
// The log comes from motion_io's seeded NC dry-run generator (motion_io/synth.hpp: acceleration-
// limited corners, unequal sampling, quantized positions) over a program written here: layers of
// 3 mm over a 150 x 100 mm stock, each cleared by passes along X that step 1 mm in Y, alternating
// direction (so up and down milling alternate), with a retract between layers; as many layers as
// fill --minutes of motion (the stock is made deep enough for them).
//
// Then 1 s zooms recomputed on demand (`cutload predict --window`) at 10, 50 and 95 % of the run:
// wall, CPU and peak memory of each, and whether its rows are byte for byte the whole run's.
//
// Then through the service: a `cutload serve` child (SQLite store, one worker) gets the log and
// spec uploaded as a run; printed are the time from upload to done, the server's peak resident
// memory (VmHWM), the bytes stored (database, WAL, uploads), and the latency of /forces windows
// on the finished run (the whole run, and zooms of 0.05 to 5 s, max_points 2000, the plot's four
// force channels; one client, p50 and p99), then the time of 1 s windows recomputed at full
// resolution (resolution=full) at 10, 50 and 95 % of the run, each walked from the run's last stock
// checkpoint before it.
//
// The CLI and the service run with --max-force-rows 1e9: the default bound (2e8 rows, about two
// hours of cutting) would refuse runs of --minutes 120 and more, and the bench measures the scale.
//
// Usage: bench_long [--minutes M] [--device cpu|opencl] [--via cli|service|both] [--forces csv|bin] [--cutload PATH] [--keep]
//   defaults: 60 minutes, opencl, both, csv (the CLI's --out FORCES.csv, or FORCES.bin), ../cli/cutload beside
//   this program; --keep keeps the folder.
#include "bench_server.hpp"
#include "bench_util.hpp"
#include "server/server.hpp"
#include "motion_io/nc_program.hpp"
#include "motion_io/synth.hpp"

#include <httplib.h>
#include <nlohmann/json.hpp>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

using namespace cutload;
using namespace cutload::bench;
namespace fs = std::filesystem;

namespace {

constexpr double kStockXmm = 150, kStockYmm = 100, kToolRadiusMm = 4;
constexpr double kAeMm = 1, kApMm = 3, kFeedMmMin = 6000;

struct Program {
    std::string text;
    int layers = 0;
    double depth_mm = 0;
};

Program roughing_program(double minutes) {
    const int passes = int(std::ceil(kStockYmm / kAeMm)) + 1;
    const double pass_mm = kStockXmm + 2 * kToolRadiusMm + 4 + kAeMm;
    const double layer_s = passes * pass_mm / kFeedMmMin * 60 + 3;
    Program p;
    p.layers = std::max(1, int(std::ceil(minutes * 60 / layer_s)));
    p.depth_mm = p.layers * kApMm;
    std::ostringstream o;
    o << "G21 G90 G54\n";
    int n = 10;
    auto line = [&](const std::string& s) {
        o << 'N' << n << ' ' << s << '\n';
        n += 10;
    };
    const double x_lo = -kToolRadiusMm - 2, x_hi = kStockXmm + kToolRadiusMm + 2;
    char buf[128];
    line("G0 X" + std::to_string(x_lo) + " Y" + std::to_string(kAeMm - kToolRadiusMm) + " Z5 S10000 M03");
    for (int layer = 1; layer <= p.layers; ++layer) {
        const double z = p.depth_mm - layer * kApMm;   // the stock's top is at z = depth
        std::snprintf(buf, sizeof buf, "G0 X%.3f Y%.3f", x_lo, kAeMm - kToolRadiusMm);
        line(buf);
        std::snprintf(buf, sizeof buf, "G1 Z%.3f F3000", z);
        line(buf);
        for (int k = 0; k < passes; ++k) {
            const double y = kAeMm - kToolRadiusMm + k * kAeMm;
            const bool forward = k % 2 == 0;
            if (k > 0) {
                std::snprintf(buf, sizeof buf, "G1 Y%.3f F%.0f", y, kFeedMmMin);
                line(buf);
            }
            std::snprintf(buf, sizeof buf, "G1 X%.3f F%.0f", forward ? x_hi : x_lo, kFeedMmMin);
            line(buf);
        }
        std::snprintf(buf, sizeof buf, "G0 Z%.3f", p.depth_mm + 5);
        line(buf);
    }
    line("M05");
    line("M30");
    p.text = o.str();
    return p;
}

std::string run_spec_json(double depth_mm) {
    std::ifstream in(std::string(CUTLOAD_SOURCE_DIR) + "/data/demo_run.json");
    std::stringstream ss;
    ss << in.rdbuf();
    std::string s = ss.str();
    const std::string from = "\"stock\": {\"box_mm\": {\"min\": [0, 0, 0], \"max\": [105, 90, 30]}}";
    const std::size_t at = s.find(from);
    if (at == std::string::npos) return {};
    char stock[160];
    std::snprintf(stock, sizeof stock, "\"stock\": {\"box_mm\": {\"min\": [0, 0, 0], \"max\": [%.0f, %.0f, %.0f]}}", kStockXmm,
                  kStockYmm, depth_mm);
    s.replace(at, from.size(), stock);
    return s;
}

// A command's run and what it printed.
struct Child : ChildRun {
    std::string out;
};

// Its standard output, then its standard error (where cutload says why it failed).
Child run_and_read(const std::vector<std::string>& args, const fs::path& out_file) {
    Child c;
    const std::string err_file = out_file.string() + ".err";
    static_cast<ChildRun&>(c) = run_child(args, out_file.string(), err_file);
    std::stringstream ss;
    for (const std::string& f : {out_file.string(), err_file}) {
        std::ifstream in(f);
        ss << in.rdbuf();
    }
    c.out = ss.str();
    return c;
}

}  // namespace

namespace {

std::uintmax_t tree_bytes(const fs::path& dir) {
    std::uintmax_t bytes = 0;
    for (const auto& e : fs::recursive_directory_iterator(dir))
        if (e.is_regular_file()) bytes += e.file_size();
    return bytes;
}

double pct(std::vector<double> v, double p) {
    if (v.empty()) return 0;
    std::sort(v.begin(), v.end());
    return v[std::min(v.size() - 1, std::size_t(p * double(v.size() - 1) + 0.5))];
}

int through_service(const fs::path& cutload, const fs::path& dir, const std::string& device) {
    using nlohmann::json;
    const fs::path data = dir / "service";
    fs::create_directories(data);
    const std::string db = (data / "cutload.db").string();
    const std::string writer = server::create_api_key(db, server::Role::Write, "bench_long");
    std::string log_text, spec_text;
    {
        std::ifstream a(dir / "roughing_dryrun.csv", std::ios::binary), b(dir / "run.json");
        std::stringstream sa, sb;
        sa << a.rdbuf();
        sb << b.rdbuf();
        log_text = sa.str();
        spec_text = sb.str();
    }
    ServerProcess srv(fs::absolute(cutload).string(),
                      {"serve", "--listen", "127.0.0.1:0", "--db", db, "--data-dir", (data / "files").string(), "--workers",
                       "1", "--device", device, "--max-force-rows", "1e9"});
    httplib::Client cli("127.0.0.1", srv.port);
    cli.set_bearer_token_auth(writer.c_str());
    cli.set_read_timeout(600, 0);
    cli.set_write_timeout(600, 0);
    std::printf("load average before: %s\n", load_average().c_str());
    const auto t0 = std::chrono::steady_clock::now();
    httplib::MultipartFormDataItems items{{"log", log_text, "roughing_dryrun.csv", "text/csv"}, {"spec", spec_text, "", ""}};
    auto r = cli.Post("/api/v1/runs", items);
    if (!r || r->status != 202) {
        std::printf("upload failed: %s\n", r ? r->body.c_str() : "no response");
        return 1;
    }
    log_text.clear();
    log_text.shrink_to_fit();
    const std::string run_path = "/api/v1/runs/" + std::to_string(json::parse(r->body)["id"].get<long long>());
    json run;
    do {
        std::this_thread::sleep_for(std::chrono::milliseconds(500));
        auto g = cli.Get(run_path.c_str());
        if (!g) continue;
        run = json::parse(g->body);
    } while (run.is_null() || run["state"] == "queued" || run["state"] == "running");
    const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::printf("load average after:  %s\n", load_average().c_str());
    if (run["state"] != "done") {
        std::printf("run %s: %s\n", run["state"].get<std::string>().c_str(), run["error"].dump().c_str());
        return 1;
    }
    const json& sum = run["summary"];
    const double simulated_s = sum.value("simulated_s", 0.0);
    std::uintmax_t checkpoint_bytes = 0;
    int checkpoints = 0;
    for (const auto& e : fs::recursive_directory_iterator(data))
        if (e.is_regular_file() && e.path().filename().string().ends_with(".stock.gz")) {
            checkpoint_bytes += e.file_size();
            ++checkpoints;
        }
    std::printf("cutload serve --device %s (upload to done):\n", device.c_str());
    std::printf("  motion %.1f s, wall %.1f s, %.1fx real time, server peak RSS %.0f MB, stored %.1f MB "
                "(database, WAL and uploads); %lld force rows, %lld blocks\n",
                simulated_s, wall_s, wall_s > 0 ? simulated_s / wall_s : 0.0, double(rss_kib(srv.pid, "VmHWM:")) / 1024,
                double(tree_bytes(data)) / 1e6, sum.value("samples", 0LL), sum.value("blocks", 0LL));
    std::printf("  of which %d stock checkpoints: %.1f MB\n", checkpoints, double(checkpoint_bytes) / 1e6);

    // What a plot asks of the finished run: the whole run, then zooms.
    std::vector<double> whole_ms, zoom_ms;
    std::mt19937 rng(20261123);
    std::uniform_real_distribution<double> u(0, 1);
    const std::string channels = "&channels=fx_N,fy_N,fz_N,f_N";
    for (int i = 0; i < 220; ++i) {
        char path[512];
        if (i < 20) {
            std::snprintf(path, sizeof path, "%s/forces?max_points=2000%s", run_path.c_str(), channels.c_str());
        } else {
            const double w = 0.05 * std::pow(100.0, u(rng));
            const double from = u(rng) * (simulated_s - w);
            std::snprintf(path, sizeof path, "%s/forces?max_points=2000&from_s=%.6f&to_s=%.6f%s", run_path.c_str(), from,
                          from + w, channels.c_str());
        }
        const auto q0 = std::chrono::steady_clock::now();
        auto g = cli.Get(path);
        const double ms = 1e3 * std::chrono::duration<double>(std::chrono::steady_clock::now() - q0).count();
        if (!g || g->status != 200) {
            std::printf("  %s: %s\n", path, g ? g->body.c_str() : "no response");
            return 1;
        }
        (i < 20 ? whole_ms : zoom_ms).push_back(ms);
    }
    std::printf("  /forces: whole run p50 %.1f ms p99 %.1f ms (20 queries); zoom 0.05-5 s p50 %.1f ms p99 %.1f ms "
                "(200 queries); server RSS now %.0f MB\n",
                pct(whole_ms, 0.5), pct(whole_ms, 0.99), pct(zoom_ms, 0.5), pct(zoom_ms, 0.99),
                double(rss_kib(srv.pid)) / 1024);
    // The same 1 s windows as the CLI's, recomputed at full resolution (resolution=full).
    for (double at : {0.10, 0.50, 0.95}) {
        const double from_s = std::floor(at * simulated_s);
        char path[512];
        std::snprintf(path, sizeof path, "%s/forces?max_points=20000&from_s=%.0f&to_s=%.0f&resolution=full%s",
                      run_path.c_str(), from_s, from_s + 1, channels.c_str());
        const auto q0 = std::chrono::steady_clock::now();
        auto g = cli.Get(path);
        const double s_taken = std::chrono::duration<double>(std::chrono::steady_clock::now() - q0).count();
        if (!g || g->status != 200) {
            std::printf("  %s: %s\n", path, g ? g->body.c_str() : "no response");
            return 1;
        }
        const json w = json::parse(g->body);
        std::printf("  /forces?resolution=full %.0f..%.0f s: %.2f s, walked from %.1f s, %d rows (decimated: %s); server "
                    "RSS now %.0f MB\n",
                    from_s, from_s + 1, s_taken, w.value("walked_from_s", -1.0), w.value("count", 0),
                    w.value("decimated", false) ? "yes" : "no", double(rss_kib(srv.pid)) / 1024);
    }
    return 0;
}

}  // namespace

int through_cli(const fs::path& cutload, const fs::path& dir, const std::string& device, const std::string& forces_file);
int windows_through_cli(const fs::path& cutload, const fs::path& dir, const std::string& device,
                        const std::string& forces_file, double simulated_s);

int main(int argc, char** argv) {
    double minutes = 60;
    std::string device = "opencl";
    fs::path cutload = fs::path(argv[0]).parent_path() / ".." / "cli" / "cutload";
    bool keep = false;
    std::string via = "both", forces_file = "FORCES.csv";
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        if (a == "--minutes" && i + 1 < argc) minutes = std::atof(argv[++i]);
        else if (a == "--device" && i + 1 < argc) device = argv[++i];
        else if (a == "--cutload" && i + 1 < argc) cutload = argv[++i];
        else if (a == "--keep") keep = true;
        else if (a == "--via" && i + 1 < argc) via = argv[++i];
        else if (a == "--forces" && i + 1 < argc && (std::string(argv[i + 1]) == "csv" || std::string(argv[i + 1]) == "bin"))
            forces_file = std::string("FORCES.") + argv[++i];
        else {
            std::fprintf(stderr, "usage: bench_long [--minutes M] [--device cpu|opencl] [--via cli|service|both] [--forces csv|bin] [--cutload PATH] [--keep]\n");
            return 2;
        }
    }
    if (!(minutes > 0) || !fs::exists(cutload)) {
        std::fprintf(stderr, "bench_long: need --minutes > 0 and the cutload binary (%s)\n", cutload.c_str());
        return 2;
    }
    const fs::path dir = fs::temp_directory_path() / ("cutload_bench_long_" + std::to_string(getpid()));
    fs::create_directories(dir);

    const Program program = roughing_program(minutes);
    const std::string spec = run_spec_json(program.depth_mm);
    if (spec.empty()) {
        std::fprintf(stderr, "bench_long: data/demo_run.json does not have the stock this bench replaces\n");
        return 2;
    }
    {
        std::ofstream(dir / "run.json") << spec;
        std::ofstream(dir / "roughing.nc") << program.text;
    }
    const auto g0 = std::chrono::steady_clock::now();
    std::size_t log_rows = 0;
    {
        motion_io::NcReadOptions read;
        const double setup_offset_mm[3] = {-200, 300, 350};   // data/demo_run.json: work zero at machine (200, -300, -350)
        read.work_offsets_mm = motion_io::default_work_offsets(setup_offset_mm);
        motion_io::NcDryRunSpec s;
        s.program = motion_io::parse_nc_program(program.text, "roughing.nc", read);
        const double start[3] = {190, -300, -300};
        std::copy(start, start + 3, s.start_mm);
        s.machine.max_accel_mm_s2 = 2500;
        s.seed = 20261123;
        std::ofstream out(dir / "roughing_dryrun.csv", std::ios::binary);
        log_rows = motion_io::synthesize_nc_dry_run(s, out);
    }
    const double gen_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - g0).count();
    std::printf("bench_long: %d layers of ap %.0f mm over %.0f x %.0f mm, ae %.0f mm, F%.0f, S10000\n", program.layers, kApMm,
                kStockXmm, kStockYmm, kAeMm, kFeedMmMin);
    std::printf("log: %zu rows, %.1f MB, generated in %.1f s (%s)\n", log_rows,
                double(fs::file_size(dir / "roughing_dryrun.csv")) / 1e6, gen_s, (dir / "roughing_dryrun.csv").c_str());
    int rc = 0;
    if (via == "cli" || via == "both") rc |= through_cli(cutload, dir, device, forces_file);
    if (via == "service" || via == "both") rc |= through_service(cutload, dir, device);
    if (keep) std::printf("kept: %s\n", dir.c_str());
    else fs::remove_all(dir);
    return rc;
}

int through_cli(const fs::path& cutload, const fs::path& dir, const std::string& device, const std::string& forces_file) {
    std::printf("load average before: %s\n", load_average().c_str());
    const Child c = run_and_read({fs::absolute(cutload).string(), "predict", (dir / "roughing_dryrun.csv").string(), "--spec",
                               (dir / "run.json").string(), "--out", (dir / forces_file).string(), "--blocks",
                               (dir / "BLOCKS.csv").string(), "--device", device, "--max-force-rows", "1e9", "-q"},
                              dir / "predict.out");
    std::printf("load average after:  %s\n", load_average().c_str());
    if (c.status != 0) {
        std::printf("cutload predict failed (exit status %d); its output:\n%s\n", c.status, c.out.c_str());
        return 1;
    }
    // The prediction's own figures: "simulated S s in W s wall (Rx real time); N angle steps, C cutting".
    double simulated_s = 0;
    if (const std::size_t at = c.out.find("simulated "); at != std::string::npos)
        simulated_s = std::atof(c.out.c_str() + at + 10);
    std::uintmax_t bytes = 0;
    for (const std::string& f : {forces_file, std::string("BLOCKS.csv")}) bytes += fs::file_size(dir / f);
    std::printf("cutload predict --device %s --out %s (CLI, end to end):\n", device.c_str(), forces_file.c_str());
    std::printf("  motion %.1f s (%.1f min), wall %.1f s, %.1fx real time, CPU %.1f s, peak RSS %.0f MB, written %.2f GB\n",
                simulated_s, simulated_s / 60, c.wall_s, c.wall_s > 0 ? simulated_s / c.wall_s : 0.0, c.cpu_s, c.peak_rss_mb,
                double(bytes) / 1e9);
    std::printf("  its report: %s", c.out.substr(0, c.out.find('\n', c.out.find("simulated")) + 1).c_str());
    return windows_through_cli(cutload, dir, device, forces_file, simulated_s);
}

namespace {

// The first byte of the first line at or after `offset` whose time is >= t_s, in a FORCES.csv whose
// rows are in time order (one session): binary search on byte offsets.
std::uintmax_t first_line_at(std::ifstream& in, std::uintmax_t size, double t_s) {
    auto line_after = [&](std::uintmax_t at, double& line_t_s) {
        in.clear();
        in.seekg(std::streamoff(at));
        std::string line;
        if (at > 0) std::getline(in, line);   // the rest of a line cut in the middle (or the header)
        const std::uintmax_t start = std::uintmax_t(in.tellg());
        if (!std::getline(in, line)) return size;
        line_t_s = std::atof(line.c_str());
        return start;
    };
    std::uintmax_t lo = 0, hi = size;   // the answer lies in [lo, hi]
    while (hi - lo > 1) {
        const std::uintmax_t mid = lo + (hi - lo) / 2;
        double mid_t_s = 0;
        const std::uintmax_t start = line_after(mid, mid_t_s);
        if (start >= size || mid_t_s >= t_s) hi = mid;
        else lo = mid;
    }
    double t = 0;
    return line_after(hi, t);
}

std::string forces_lines_between(const fs::path& file, double from_s, double to_s) {
    std::ifstream in(file, std::ios::binary);
    const std::uintmax_t size = fs::file_size(file);
    const std::uintmax_t a = first_line_at(in, size, from_s), b = first_line_at(in, size, to_s);
    std::string text(b > a ? b - a : 0, '\0');
    in.clear();
    in.seekg(std::streamoff(a));
    in.read(text.data(), std::streamsize(text.size()));
    return text;
}

}  // namespace

// Zooms recomputed on demand (cutload predict --window): 1 s windows at 10, 50 and 95 % of the
// run, each timed as a user runs it and compared byte for byte with the whole run's rows there.
int windows_through_cli(const fs::path& cutload, const fs::path& dir, const std::string& device,
                        const std::string& forces_file, double simulated_s) {
    if (!(simulated_s > 10)) return 0;
    int rc = 0;
    std::printf("cutload predict --window (1 s zooms recomputed at full resolution), load average %s:\n",
                load_average().c_str());
    for (double at : {0.10, 0.50, 0.95}) {
        const double from_s = std::floor(at * simulated_s), to_s = from_s + 1;
        char window[64];
        std::snprintf(window, sizeof window, "%.0f:%.0f", from_s, to_s);
        const Child c = run_and_read({fs::absolute(cutload).string(), "predict", (dir / "roughing_dryrun.csv").string(),
                                      "--spec", (dir / "run.json").string(), "--out", (dir / "WINDOW.csv").string(),
                                      "--window", window, "--device", device, "--max-force-rows", "1e9", "-q"},
                                     dir / "window.out");
        if (c.status != 0) {
            std::printf("  --window %s failed (exit status %d): %s\n", window, c.status, c.out.c_str());
            rc = 1;
            continue;
        }
        std::string same = "not compared (the whole run wrote FORCES.bin)";
        if (forces_file == "FORCES.csv") {
            std::ifstream w(dir / "WINDOW.csv", std::ios::binary);
            std::string header, rows;
            std::getline(w, header);
            std::stringstream ss;
            ss << w.rdbuf();
            rows = ss.str();
            const std::string whole = forces_lines_between(dir / forces_file, from_s, to_s);
            const std::size_t n = std::size_t(std::count(rows.begin(), rows.end(), '\n'));
            same = rows == whole ? "identical to the whole run's " + std::to_string(n) + " rows there"
                                 : "DIFFERENT from the whole run's rows there (" + std::to_string(n) + " rows against " +
                                       std::to_string(std::count(whole.begin(), whole.end(), '\n')) + ")";
            if (rows != whole) rc = 1;
        }
        std::printf("  %-12s wall %.2f s, CPU %.2f s, peak RSS %.0f MB; %s\n", window, c.wall_s, c.cpu_s, c.peak_rss_mb,
                    same.c_str());
    }
    return rc;
}
