// Drain time of queued runs by `cutload worker` processes on PostgreSQL (issue 18), with one
// worker killed (kill -9) every --kill-every-s seconds and restarted. An API-only `cutload serve
// --workers 0` takes the uploads; N workers compute them. For each N in --workers it prints the
// time from the workers' start until every run is done, the kills, how often runs were claimed,
// and checks that no run was lost (every run done in the store) or stored twice (one set of
// blocks, at most one "run K done" line over all workers' logs).
//
//   bench_workers --db postgresql://... [--runs 60] [--workers 1,2,3] [--kill-every-s 10]
//                 [--log-s 1.0] [--lease-s 5] [--cutload PATH]
//
// The database must exist (an empty one: scripts/pg_test_cluster.sh start DIR prints a cluster's
// URL). Each run is a straight slot (slot log of --log-s seconds, 10000 rpm, fine steps).
#include "bench_server.hpp"
#include "bench_util.hpp"
#include "server/server.hpp"

#include <httplib.h>
#include <nlohmann/json.hpp>

#include <fcntl.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace fs = std::filesystem;
using json = nlohmann::json;
using Clock = std::chrono::steady_clock;

namespace {

std::string slot_log_csv(double duration_s) {
    std::ostringstream o;
    o << "t,x,y,z,feed,spindle,block\n";
    const double feed_mm_min = 1200, v_mm_s = feed_mm_min / 60.0;
    const int n = static_cast<int>(duration_s / 0.002);
    for (int i = 0; i < n; ++i) {
        const double t = i * 0.002;
        o << t << ',' << -6.0 + v_mm_s * t << ",5,-2," << feed_mm_min << ",10000," << (t < duration_s / 2 ? "N10" : "N20") << '\n';
    }
    return o.str();
}

json slot_spec() {
    return json::parse(R"({
      "tool": {"shape": "flat", "diameter_mm": 8, "flutes": 2, "helix_deg": 30, "corner_radius_mm": 0,
               "flute_length_mm": 20, "stickout_mm": 30},
      "material": {"name": "A7050", "Ktc_N_mm2": 800, "Krc_N_mm2": 300, "Kac_N_mm2": 100,
                   "Kte_N_mm": 20, "Kre_N_mm": 20, "Kae_N_mm": 5},
      "stock": {"box_mm": {"min": [0, 0, -10], "max": [1000, 10, 0]}},
      "resolution": {"angle_step_deg": 0.5, "axial_step_mm": 0.1, "grid_mm": 0.1}})");
}

pid_t spawn(const std::string& cutload, const std::vector<std::string>& args, const fs::path& log) {
    const pid_t pid = ::fork();
    if (pid == 0) {
        ::prctl(PR_SET_PDEATHSIG, SIGKILL);   // no worker outlives the bench
        const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
        ::dup2(fd, STDOUT_FILENO);
        ::dup2(fd, STDERR_FILENO);
        std::vector<char*> argv{const_cast<char*>(cutload.c_str())};
        for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
        argv.push_back(nullptr);
        ::execv(cutload.c_str(), argv.data());
        ::_exit(127);
    }
    return pid;
}

std::string read_text(const fs::path& p) {
    std::ifstream in(p);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

double loadavg1() {
    const std::string text = cutload::bench::load_average();
    return text == "unknown" ? 0.0 : std::stod(text);
}

}  // namespace

int main(int argc, char** argv) {
    std::string db, cutload = (fs::path(argv[0]).parent_path() / ".." / "cli" / "cutload").string(), workers_arg = "1,2,3";
    int runs = 60;
    double kill_every_s = 10, log_s = 1.0, lease_s = 5;
    for (int i = 1; i + 1 < argc; i += 2) {
        const std::string a = argv[i], v = argv[i + 1];
        if (a == "--db") db = v;
        else if (a == "--runs") runs = std::stoi(v);
        else if (a == "--workers") workers_arg = v;
        else if (a == "--kill-every-s") kill_every_s = std::stod(v);
        else if (a == "--log-s") log_s = std::stod(v);
        else if (a == "--lease-s") lease_s = std::stod(v);
        else if (a == "--cutload") cutload = v;
        else {
            std::fprintf(stderr, "bench_workers: unknown option %s\n", a.c_str());
            return 2;
        }
    }
    if (db.rfind("postgres", 0) != 0) {
        std::fprintf(stderr, "usage: bench_workers --db postgresql://... [--runs N] [--workers 1,2,3] [--kill-every-s S] "
                             "[--log-s S] [--lease-s S] [--cutload PATH]\n");
        return 2;
    }
    std::vector<int> counts;
    for (std::stringstream ss(workers_arg); ss.good();) {
        std::string item;
        std::getline(ss, item, ',');
        if (!item.empty()) counts.push_back(std::stoi(item));
    }

    const fs::path dir = fs::temp_directory_path() / ("cutload-bench-workers-" + std::to_string(::getpid()));
    fs::create_directories(dir / "data");
    const std::string key = cutload::server::create_api_key(db, cutload::server::Role::Write, "bench workers");
    cutload::bench::ServerProcess api(cutload, {"serve", "--listen", "127.0.0.1:0", "--db", db, "--data-dir",
                                                (dir / "data").string(), "--workers", "0", "--lease-s",
                                                std::to_string(lease_s), "--max-pending-jobs", "100000"});
    httplib::Client c("127.0.0.1", api.port);
    c.set_bearer_token_auth(key.c_str());
    c.set_read_timeout(60, 0);
    const std::string log_text = slot_log_csv(log_s);
    const std::string spec = slot_spec().dump();
    std::printf("bench_workers: %d runs of a %.2f s slot log per phase, kill -9 every %.0f s, leases of %.1f s, %u cores\n",
                runs, log_s, kill_every_s, lease_s, std::thread::hardware_concurrency());

    bool all_ok = true;
    for (const int n : counts) {
        // Queue the phase's runs before any worker starts.
        std::vector<long long> ids;
        for (int i = 0; i < runs; ++i) {
            httplib::MultipartFormDataItems items{{"log", log_text, "slot.csv", "text/csv"}, {"spec", spec, "", "application/json"}};
            auto r = c.Post("/api/v1/runs", items);
            if (!r || r->status != 202) {
                std::fprintf(stderr, "upload failed: %s\n", r ? r->body.c_str() : "no answer");
                return 1;
            }
            ids.push_back(json::parse(r->body)["id"].get<long long>());
        }
        std::vector<pid_t> pids(static_cast<std::size_t>(n));
        std::vector<fs::path> logs;
        auto start_worker = [&](std::size_t slot) {
            const fs::path log = dir / ("w" + std::to_string(n) + "-" + std::to_string(slot) + "-" + std::to_string(logs.size()) + ".log");
            logs.push_back(log);
            pids[slot] = spawn(cutload, {"worker", "--db", db, "--data-dir", (dir / "data").string(), "--device", "cpu",
                                          "--lease-s", std::to_string(lease_s), "--drain-s", "0"},
                               log);
        };
        const auto t0 = Clock::now();
        for (std::size_t k = 0; k < pids.size(); ++k) start_worker(k);
        int kills = 0;
        auto next_kill = t0 + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(kill_every_s));
        double load_max = 0;
        for (;;) {
            int done = 0, failed = 0;
            for (const long long id : ids) {
                auto r = c.Get(("/api/v1/runs/" + std::to_string(id)).c_str());
                if (!r || r->status != 200) continue;
                const std::string state = json::parse(r->body)["state"];
                done += state == "done";
                failed += state == "failed" || state == "cancelled";
            }
            load_max = std::max(load_max, loadavg1());
            if (done + failed == runs) {
                if (failed) {
                    std::printf("  %d runs failed\n", failed);
                    all_ok = false;
                }
                break;
            }
            if (kill_every_s > 0 && Clock::now() >= next_kill) {
                const std::size_t slot = static_cast<std::size_t>(kills) % pids.size();
                ::kill(pids[slot], SIGKILL);
                ::waitpid(pids[slot], nullptr, 0);
                ++kills;
                start_worker(slot);
                next_kill += std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(kill_every_s));
            }
            std::this_thread::sleep_for(std::chrono::milliseconds(200));
        }
        const double drain_s = std::chrono::duration<double>(Clock::now() - t0).count();
        for (const pid_t p : pids) {
            ::kill(p, SIGTERM);
            ::waitpid(p, nullptr, 0);
        }
        // Lost or stored twice: one "run K done" line per run over every generation's log.
        std::string all;
        for (const auto& l : logs) all += read_text(l);
        std::map<long long, int> done_lines;
        static const std::regex done_re(R"(run (\d+) done in)");
        for (auto it = std::sregex_iterator(all.begin(), all.end(), done_re); it != std::sregex_iterator(); ++it)
            ++done_lines[std::stoll((*it)[1])];
        // Lost: not done in the store. Stored twice: two "done" lines, or not the one set of
        // blocks (a slot run has 2). A kill between a worker's commit and its log line leaves a
        // run done without its line: counted apart.
        int lost = 0, twice = 0, reclaimed = 0, unlogged = 0;
        for (const long long id : ids) {
            const int d = done_lines.count(id) ? done_lines[id] : 0;
            auto r = c.Get(("/api/v1/runs/" + std::to_string(id)).c_str());
            const json run = r && r->status == 200 ? json::parse(r->body) : json::object();
            lost += run.value("state", "") != "done";
            auto b = c.Get(("/api/v1/runs/" + std::to_string(id) + "/blocks").c_str());
            const std::size_t blocks = b && b->status == 200 ? json::parse(b->body)["items"].size() : 0;
            twice += d > 1 || (run.value("state", "") == "done" && blocks != 2);
            unlogged += d == 0;
            if (run.value("attempts", 0) > 1) ++reclaimed;
        }
        all_ok = all_ok && lost == 0 && twice == 0;
        std::printf("workers %d: drained %d runs in %.1f s (%.1f runs/min), %d kill -9, %d runs claimed again, "
                    "lost %d, stored twice %d (%d done without a log line: killed after the commit), "
                    "load average (1 min) up to %.2f\n",
                    n, runs, drain_s, 60.0 * runs / drain_s, kills, reclaimed, lost, twice, unlogged, load_max);
        std::fflush(stdout);
    }
    std::error_code ec;
    fs::remove_all(dir, ec);
    return all_ok ? 0 : 1;
}
