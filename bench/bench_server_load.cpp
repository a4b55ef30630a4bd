// Load test of the service (issue 4): a `cutload serve` child process holds a run of >= 10^6
// force samples; N keep-alive connections (client threads in this process) ask it what a plot
// and a shop MES ask, back to back with no think time (the worst case for that many clients):
//
//   70 %  zoom:     forces, a window of log-uniform width 0.05 .. 5 s at a uniform position
//   10 %  overview: forces, the whole run (what a plot asks when it opens the run)
//   20 %  blocks:   the per-block summary list (what an MES reads per run)
//
// Forces queries ask max_points=2000 (about a plot's pixel width) and the four force channels a
// force plot shows (fx_N,fy_N,fz_N,f_N), or every channel with --channels all. --gzip offers
// "gzip, deflate, br" as a browser does (the client then inflates the answers, as a browser would).
// Prints per repetition p50/p99 per kind and overall, requests/s, errors, the server's CPU per
// request and the load average; then the medians over repetitions and the server's RSS at the
// start and end of the load.
//
//   bench_server_load [--duration S (30)] [--repeat N (3)] [--connections N (32)]
//                     [--samples N (1000000)] [--channels plot|all] [--gzip] [--cache-mb MB (128)]
//                     [--cutload PATH (the cutload built next to this program)]
//                     [--db postgresql://... (an empty database; default: an SQLite file in a temporary folder)]
//
// Targets (issue 4): p99 < 50 ms, no errors, memory flat over 5 minutes (--duration 300 --repeat 1).
#include "server/server.hpp"

#include "bench_server.hpp"

#include <httplib.h>
#include <nlohmann/json.hpp>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace {

using cutload::bench::rss_kib;
using cutload::bench::ServerProcess;
namespace fs = std::filesystem;
using nlohmann::json;
using Clock = std::chrono::steady_clock;

struct CpuTimes {
    double user_s = 0, sys_s = 0;
};

// utime and stime of a process.
CpuTimes cpu_times(pid_t pid) {
    std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
    std::string stat((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::istringstream rest(stat.substr(stat.rfind(')') + 2));
    std::string field;
    CpuTimes t;
    const double tick_s = 1.0 / static_cast<double>(sysconf(_SC_CLK_TCK));
    for (int i = 3; i <= 15 && rest >> field; ++i) {
        if (i == 14) t.user_s = std::atof(field.c_str()) * tick_s;
        if (i == 15) t.sys_s = std::atof(field.c_str()) * tick_s;
    }
    return t;
}

std::string loadavg() {
    std::ifstream in("/proc/loadavg");
    std::string a, b, c;
    in >> a >> b >> c;
    return a + " " + b + " " + c;
}

// A slot along X: 10000 rpm and 2 degree steps give 30000 force samples per cutting second.
std::string slot_log(double duration_s) {
    std::ostringstream o;
    o << "t,x,y,z,feed,spindle,block\n";
    const int n = static_cast<int>(duration_s / 0.002);
    for (int i = 0; i < n; ++i) {
        const double t = i * 0.002;
        o << t << ',' << -6.0 + 20.0 * t << ",5,-2,1200,10000,N" << (10 + 10 * static_cast<int>(t / 2.0)) << '\n';
    }
    return o.str();
}

json slot_spec(double length_mm) {
    json spec = json::parse(R"({
      "tool": {"shape": "flat", "diameter_mm": 8, "flutes": 2, "helix_deg": 30, "corner_radius_mm": 0,
               "flute_length_mm": 20, "stickout_mm": 30, "holder": {"diameter_mm": 32, "length_mm": 40}},
      "material": {"name": "A7050", "Ktc_N_mm2": 800, "Krc_N_mm2": 300, "Kac_N_mm2": 100,
                   "Kte_N_mm": 20, "Kre_N_mm": 20, "Kae_N_mm": 5}})");
    spec["stock"] = {{"box_mm", {{"min", {0, 0, -10}}, {"max", {length_mm, 10, 0}}}}};
    return spec;
}

double percentile(std::vector<double> v, double p) {
    if (v.empty()) return 0;
    auto k = static_cast<std::size_t>(p * static_cast<double>(v.size() - 1));
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
    return v[k];
}

double median(std::vector<double> v) { return percentile(std::move(v), 0.5); }

std::string fmt_mib(std::uintmax_t bytes) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.0f MiB", static_cast<double>(bytes) / (1 << 20));
    return buf;
}

enum Kind { Zoom, Overview, Blocks, kKinds };
const char* kKindNames[kKinds] = {"zoom 0.05-5 s", "overview", "blocks"};

struct Rep {
    double p50 = 0, p99 = 0, max = 0, rps = 0, server_cpu_ms = 0, server_sys_ms = 0;
    double kind_p50[kKinds] = {}, kind_p99[kKinds] = {};
    long requests = 0, errors = 0;
};

}  // namespace

int main(int argc, char** argv) {
    double duration_s = 30, samples_wanted = 1e6, cache_mb = 128;
    int connections = 32, repeats = 3;
    bool gzip = false;
    std::string channels = "&channels=fx_N,fy_N,fz_N,f_N";
    fs::path cutload = fs::read_symlink("/proc/self/exe").parent_path().parent_path() / "cli" / "cutload";
    std::string db_arg;   // --db: a store other than the default SQLite file (PostgreSQL)
    for (int i = 1; i < argc; i += 2) {
        if (std::string(argv[i]) == "--gzip") {
            gzip = true;
            --i;
            continue;
        }
        if (i + 1 >= argc) {
            std::fprintf(stderr, "%s needs a value\n", argv[i]);
            return 2;
        }
        const std::string a = argv[i], v = argv[i + 1];
        if (a == "--duration") duration_s = std::atof(v.c_str());
        else if (a == "--repeat") repeats = std::max(1, std::atoi(v.c_str()));
        else if (a == "--connections") connections = std::atoi(v.c_str());
        else if (a == "--samples") samples_wanted = std::atof(v.c_str());
        else if (a == "--cache-mb") cache_mb = std::atof(v.c_str());
        else if (a == "--cutload") cutload = v;
        else if (a == "--db") db_arg = v;
        else if (a == "--channels" && (v == "plot" || v == "all")) channels = v == "all" ? "" : channels;
        else {
            std::fprintf(stderr,
                         "usage: bench_server_load [--duration S] [--repeat N] [--connections N] [--samples N] "
                         "[--channels plot|all] [--gzip] [--cache-mb MB] [--cutload PATH] [--db URL]\n");
            return 2;
        }
    }
    if (!fs::exists(cutload)) {
        std::fprintf(stderr, "%s not found: build the cutload target or pass --cutload PATH\n", cutload.c_str());
        return 1;
    }

    std::string tmpl = (fs::temp_directory_path() / "cutload-bench-XXXXXX").string();
    if (!::mkdtemp(tmpl.data())) return 1;
    const fs::path dir = tmpl;
    const std::string db = db_arg.empty() ? (dir / "bench.db").string() : db_arg;
    const std::string key = cutload::server::create_api_key(db, cutload::server::Role::Read, "bench reader");
    const std::string writer = cutload::server::create_api_key(db, cutload::server::Role::Write, "bench writer");
    int rc = 0;
    {
        std::vector<std::string> serve_args{"serve", "--listen", "127.0.0.1:0", "--db", db, "--workers", "1", "--device", "cpu",
                                            "--http-threads", std::to_string(connections + 8), "--cache-mb",
                                            std::to_string(cache_mb)};
        // A PostgreSQL URL names no folder for the upload.
        if (!db_arg.empty()) serve_args.insert(serve_args.end(), {"--data-dir", (dir / "data").string()});
        std::printf("store: %s\n", cutload::server::printable_db(db).c_str());
        ServerProcess srv(cutload.string(), serve_args);

        // The run: enough cutting seconds for the samples wanted, plus the 0.3 s approach in air.
        const double cut_s = samples_wanted / 30000.0 * 1.02;
        const double run_end_s = cut_s + 0.3;
        std::printf("preparing a run of %.1f s of cutting (~%.0f force samples)...\n", cut_s, samples_wanted);
        std::fflush(stdout);
        httplib::Client up("127.0.0.1", srv.port);
        up.set_bearer_token_auth(writer.c_str());
        up.set_read_timeout(300, 0);
        httplib::MultipartFormDataItems items{{"log", slot_log(run_end_s), "bench.csv", "text/csv"},
                                              {"spec", slot_spec(20.0 * run_end_s + 10).dump(), "", ""}};
        const auto t_prep = Clock::now();
        auto r = up.Post("/api/v1/runs", items);
        if (!r || r->status != 202) {
            std::fprintf(stderr, "upload failed: %s\n", r ? r->body.c_str() : "no response");
            return 1;
        }
        const std::string run_path = "/api/v1/runs/" + std::to_string(json::parse(r->body)["id"].get<int>());
        json run;
        do {
            std::this_thread::sleep_for(std::chrono::milliseconds(200));
            run = json::parse(up.Get(run_path.c_str())->body);
        } while (run["state"] == "queued" || run["state"] == "running");
        if (run["state"] != "done") {
            std::fprintf(stderr, "run %s: %s\n", run["state"].get<std::string>().c_str(), run["error"].dump().c_str());
            return 1;
        }
        // A PostgreSQL database's files are its server's: its size is not shown.
        const std::string db_size = db_arg.empty() ? fmt_mib(fs::file_size(db) + fs::file_size(db + "-wal")) : "in PostgreSQL";
        std::printf("run ready in %.1f s: %lld force samples, %lld blocks; db %s\n",
                    std::chrono::duration<double>(Clock::now() - t_prep).count(),
                    run["summary"]["samples"].get<long long>(), run["summary"]["blocks"].get<long long>(), db_size.c_str());
        std::printf("%d connections, %s channels, max_points=2000, %s, %d x %.0f s, cache %.0f MiB\n", connections,
                    channels.empty() ? "all 12" : "4 force", gzip ? "gzip offered" : "no compression", repeats,
                    duration_s, cache_mb);

        const long rss_start = rss_kib(srv.pid);
        std::vector<Rep> reps;
        for (int rep = 0; rep < repeats; ++rep) {
            std::atomic<bool> stop{false};
            std::atomic<long> errors{0}, done{0};
            std::vector<std::vector<double>> lat_ms(static_cast<std::size_t>(connections) * kKinds);
            std::vector<std::thread> threads;
            const std::string load_before = loadavg();
            const CpuTimes cpu0 = cpu_times(srv.pid);
            const auto t0 = Clock::now();
            for (int c = 0; c < connections; ++c) {
                threads.emplace_back([&, c] {
                    httplib::Client cli("127.0.0.1", srv.port);
                    cli.set_bearer_token_auth(key.c_str());
                    cli.set_keep_alive(true);
                    cli.set_tcp_nodelay(true);
                    httplib::Headers headers;
                    if (gzip) headers.emplace("Accept-Encoding", "gzip, deflate, br");
                    std::mt19937 rng(static_cast<unsigned>(1000 * rep + c));
                    std::uniform_real_distribution<double> u(0, 1);
                    char path[512];
                    while (!stop) {
                        const double pick = u(rng);
                        const Kind kind = pick < 0.7 ? Zoom : pick < 0.8 ? Overview : Blocks;
                        if (kind == Blocks) {
                            std::snprintf(path, sizeof path, "%s/blocks", run_path.c_str());
                        } else if (kind == Overview) {
                            std::snprintf(path, sizeof path, "%s/forces?max_points=2000%s", run_path.c_str(), channels.c_str());
                        } else {
                            const double w = 0.05 * std::pow(100.0, u(rng));
                            const double from = u(rng) * (run_end_s - w);
                            std::snprintf(path, sizeof path, "%s/forces?max_points=2000&from_s=%.6f&to_s=%.6f%s",
                                          run_path.c_str(), from, from + w, channels.c_str());
                        }
                        const auto q0 = Clock::now();
                        auto res = cli.Get(path, headers);
                        lat_ms[static_cast<std::size_t>(c * kKinds + kind)].push_back(
                            std::chrono::duration<double, std::milli>(Clock::now() - q0).count());
                        if (!res || res->status != 200) ++errors;
                        ++done;
                    }
                });
            }
            const double report_every_s = std::max(5.0, duration_s / 10);
            for (double t = 0; t < duration_s;) {
                const double step = std::min(report_every_s, duration_s - t);
                std::this_thread::sleep_for(std::chrono::duration<double>(step));
                t += step;
                std::printf("  t %5.0f s  server RSS %7.1f MiB  requests %ld\n", t,
                            static_cast<double>(rss_kib(srv.pid)) / 1024, done.load());
                std::fflush(stdout);
            }
            stop = true;
            for (auto& t : threads) t.join();
            const double elapsed_s = std::chrono::duration<double>(Clock::now() - t0).count();

            Rep out;
            std::vector<double> all;
            for (int k = 0; k < kKinds; ++k) {
                std::vector<double> v;
                for (int c = 0; c < connections; ++c) {
                    const auto& l = lat_ms[static_cast<std::size_t>(c * kKinds + k)];
                    v.insert(v.end(), l.begin(), l.end());
                }
                out.kind_p50[k] = percentile(v, 0.5);
                out.kind_p99[k] = percentile(v, 0.99);
                all.insert(all.end(), v.begin(), v.end());
            }
            out.requests = static_cast<long>(all.size());
            out.errors = errors;
            out.p50 = percentile(all, 0.5);
            out.p99 = percentile(all, 0.99);
            out.max = all.empty() ? 0 : *std::max_element(all.begin(), all.end());
            out.rps = static_cast<double>(all.size()) / elapsed_s;
            const CpuTimes cpu1 = cpu_times(srv.pid);
            const double per_request_ms = 1000 / std::max<double>(1, static_cast<double>(all.size()));
            out.server_cpu_ms = (cpu1.user_s - cpu0.user_s + cpu1.sys_s - cpu0.sys_s) * per_request_ms;
            out.server_sys_ms = (cpu1.sys_s - cpu0.sys_s) * per_request_ms;
            std::printf("rep %d: %ld requests, %ld errors, %.0f requests/s, p50 %.2f ms, p99 %.2f ms, max %.1f ms, "
                        "server CPU %.3f ms/request (%.3f in the kernel); load average %s -> %s\n",
                        rep + 1, out.requests, out.errors, out.rps, out.p50, out.p99, out.max, out.server_cpu_ms,
                        out.server_sys_ms,
                        load_before.c_str(), loadavg().c_str());
            for (int k = 0; k < kKinds; ++k)
                std::printf("    %-14s p50 %7.2f ms  p99 %7.2f ms\n", kKindNames[k], out.kind_p50[k], out.kind_p99[k]);
            std::fflush(stdout);
            reps.push_back(out);
        }
        const long rss_end = rss_kib(srv.pid);

        auto med = [&](auto field) {
            std::vector<double> v;
            for (const auto& r2 : reps) v.push_back(field(r2));
            return median(v);
        };
        long errors = 0;
        for (const auto& r2 : reps) errors += r2.errors;
        const double p99 = med([](const Rep& r2) { return r2.p99; });
        std::printf("\nmedian of %d: p50 %.2f ms, p99 %.2f ms, %.0f requests/s, server CPU %.3f ms/request; errors %ld\n",
                    repeats, med([](const Rep& r2) { return r2.p50; }), p99, med([](const Rep& r2) { return r2.rps; }),
                    med([](const Rep& r2) { return r2.server_cpu_ms; }), errors);
        for (int k = 0; k < kKinds; ++k)
            std::printf("    %-14s p50 %7.2f ms  p99 %7.2f ms\n", kKindNames[k],
                        med([k](const Rep& r2) { return r2.kind_p50[k]; }), med([k](const Rep& r2) { return r2.kind_p99[k]; }));
        std::printf("server RSS at load start %.1f MiB, at end %.1f MiB\n", static_cast<double>(rss_start) / 1024,
                    static_cast<double>(rss_end) / 1024);
        std::printf("targets: p99 < 50 ms %s, no errors %s\n", p99 < 50 ? "met" : "MISSED", errors == 0 ? "met" : "MISSED");
        rc = errors == 0 ? 0 : 1;
    }
    std::error_code ec;
    fs::remove_all(dir, ec);
    return rc;
}
