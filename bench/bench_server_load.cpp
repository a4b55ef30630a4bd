// Load test of the service: forces-window and blocks queries on a run with >= 10^6 force
// samples under N concurrent keep-alive connections (httplib client threads in this process).
// Prints p50/p99 latency, requests/s, errors, and the process RSS over time.
//
//   bench_server_load [--duration S (30)] [--connections N (32)] [--samples N (1000000)]
//                     [--channels LIST (all 12; e.g. fx_N,fy_N,fz_N,f_N as a force plot asks)]
//
// Targets (issue 4): p99 < 50 ms, no errors, memory flat over 5 minutes (--duration 300).
// Client and server share this process and its cores, so latencies include client work.
#include "server/server.hpp"

#include <httplib.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace {

using nlohmann::json;
using Clock = std::chrono::steady_clock;

long rss_kib() {
    std::ifstream in("/proc/self/status");
    std::string line;
    while (std::getline(in, line))
        if (line.rfind("VmRSS:", 0) == 0) return std::strtol(line.c_str() + 6, nullptr, 10);
    return 0;
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

double percentile(std::vector<double>& v, double p) {
    if (v.empty()) return 0;
    auto k = static_cast<std::size_t>(p * static_cast<double>(v.size() - 1));
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
    return v[k];
}

}  // namespace

int main(int argc, char** argv) {
    double duration_s = 30;
    int connections = 32;
    double samples_wanted = 1e6;
    std::string channels;
    for (int i = 1; i + 1 < argc; i += 2) {
        const std::string a = argv[i];
        if (a == "--duration") duration_s = std::atof(argv[i + 1]);
        else if (a == "--connections") connections = std::atoi(argv[i + 1]);
        else if (a == "--samples") samples_wanted = std::atof(argv[i + 1]);
        else if (a == "--channels") channels = std::string("&channels=") + argv[i + 1];
        else {
            std::fprintf(stderr, "usage: bench_server_load [--duration S] [--connections N] [--samples N] [--channels LIST]\n");
            return 2;
        }
    }

    namespace fs = std::filesystem;
    std::string tmpl = (fs::temp_directory_path() / "cutload-bench-XXXXXX").string();
    if (!::mkdtemp(tmpl.data())) return 1;
    const fs::path dir = tmpl;

    cutload::server::ServerOptions opt;
    opt.port = 0;
    opt.db_path = (dir / "bench.db").string();
    opt.workers = 1;
    opt.use_opencl = false;
    opt.http_threads = connections + 8;
    const std::string key = cutload::server::create_api_key(opt.db_path, cutload::server::Role::Read);
    const std::string writer = cutload::server::create_api_key(opt.db_path, cutload::server::Role::Write);
    cutload::server::Server srv(opt);
    srv.start();

    // The run: enough cutting seconds for the samples wanted, plus the 0.3 s approach in air.
    const double cut_s = samples_wanted / 30000.0 * 1.02;
    const double duration_log_s = cut_s + 0.3;
    std::printf("preparing a run of %.1f s of cutting (~%.0f force samples)...\n", cut_s, samples_wanted);
    std::fflush(stdout);
    httplib::Client up("127.0.0.1", srv.port());
    up.set_bearer_token_auth(writer.c_str());
    up.set_read_timeout(120, 0);
    httplib::MultipartFormDataItems items{{"log", slot_log(duration_log_s), "bench.csv", "text/csv"},
                                          {"spec", slot_spec(20.0 * duration_log_s + 10).dump(), "", ""}};
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
    const double run_end_s = duration_log_s;
    std::printf("run ready in %.1f s: %lld force samples, %lld blocks; db %.0f MiB\n",
                std::chrono::duration<double>(Clock::now() - t_prep).count(),
                run["summary"]["samples"].get<long long>(), run["summary"]["blocks"].get<long long>(),
                static_cast<double>(fs::file_size(opt.db_path) + fs::file_size(opt.db_path + "-wal")) / (1 << 20));

    // Query mix: windows from 10 ms (full resolution) to the whole run (decimated to 2000).
    const double widths_s[] = {0.01, 0.05, 1, 10, 1e9};
    std::atomic<bool> stop{false};
    std::atomic<long> errors{0};
    // Latencies per connection and query kind (0..4: window widths, 5: blocks).
    constexpr int kKinds = 6;
    const char* kind_names[kKinds] = {"forces 10 ms", "forces 50 ms", "forces 1 s", "forces 10 s", "forces whole run", "blocks"};
    std::vector<std::vector<double>> lat_ms(static_cast<std::size_t>(connections) * kKinds);
    std::vector<std::thread> threads;
    const long rss_start = rss_kib();
    const auto t0 = Clock::now();
    for (int c = 0; c < connections; ++c) {
        threads.emplace_back([&, c] {
            httplib::Client cli("127.0.0.1", srv.port());
            cli.set_bearer_token_auth(key.c_str());
            cli.set_keep_alive(true);
            cli.set_tcp_nodelay(true);
            std::mt19937 rng(static_cast<unsigned>(c));
            std::uniform_real_distribution<double> u(0, 1);
            for (long i = 0; !stop; ++i) {
                std::string path;
                const int kind = static_cast<int>(i % kKinds);
                if (kind == 5) {
                    path = run_path + "/blocks";
                } else {
                    const double w = widths_s[kind];
                    const double from = w >= run_end_s ? 0 : u(rng) * (run_end_s - w);
                    path = run_path + "/forces?max_points=2000&from_s=" + std::to_string(from) +
                           "&to_s=" + std::to_string(std::min(run_end_s, from + w)) + channels;
                }
                const auto q0 = Clock::now();
                auto res = cli.Get(path.c_str());
                lat_ms[static_cast<std::size_t>(c * kKinds + kind)].push_back(std::chrono::duration<double, std::milli>(Clock::now() - q0).count());
                if (!res || res->status != 200) ++errors;
            }
        });
    }
    std::printf("%8s %10s %10s\n", "t_s", "RSS_MiB", "requests");
    for (double t = 0; t < duration_s;) {
        const double step = std::min(5.0, duration_s - t);
        std::this_thread::sleep_for(std::chrono::duration<double>(step));
        t += step;
        std::size_t n = 0;
        for (const auto& v : lat_ms) n += v.size();   // racy read of sizes: a progress figure only
        std::printf("%8.0f %10.1f %10zu\n", t, static_cast<double>(rss_kib()) / 1024, n);
        std::fflush(stdout);
    }
    stop = true;
    for (auto& t : threads) t.join();
    const double elapsed_s = std::chrono::duration<double>(Clock::now() - t0).count();

    std::vector<double> all;
    for (const auto& v : lat_ms) all.insert(all.end(), v.begin(), v.end());
    const double n = static_cast<double>(all.size());
    const double p50 = percentile(all, 0.50), p99 = percentile(all, 0.99);
    const double max_ms = all.empty() ? 0 : *std::max_element(all.begin(), all.end());
    std::printf("\nconnections %d, duration %.0f s, requests %.0f, errors %ld\n", connections, elapsed_s, n, errors.load());
    std::printf("latency p50 %.2f ms, p99 %.2f ms, max %.1f ms; %.0f requests/s\n", p50, p99, max_ms, n / elapsed_s);
    for (int k = 0; k < kKinds; ++k) {
        std::vector<double> v;
        for (int c = 0; c < connections; ++c) v.insert(v.end(), lat_ms[static_cast<std::size_t>(c * kKinds + k)].begin(), lat_ms[static_cast<std::size_t>(c * kKinds + k)].end());
        std::printf("  %-18s p50 %7.2f ms  p99 %7.2f ms\n", kind_names[k], percentile(v, 0.5), percentile(v, 0.99));
    }
    std::printf("RSS start %.1f MiB, end %.1f MiB\n", static_cast<double>(rss_start) / 1024, static_cast<double>(rss_kib()) / 1024);
    std::printf("targets: p99 < 50 ms %s, no errors %s\n", p99 < 50 ? "met" : "MISSED", errors == 0 ? "met" : "MISSED");
    srv.stop();
    std::error_code ec;
    fs::remove_all(dir, ec);
    return 0;
}
