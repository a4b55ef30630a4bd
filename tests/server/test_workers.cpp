// Beyond one box (issue 18): `cutload worker` processes compute the jobs of a PostgreSQL store
// that an API-only server (--workers 0) fills. Their claims are leases: a worker killed with
// kill -9 has its run re-queued once the lease ends, one stopped (SIGSTOP) past its lease finds
// its claim gone and stores nothing, and every run is stored exactly once.
#include "harness.hpp"
#include "spawn.hpp"
#include "test_store.hpp"

#include <csignal>
#include <map>
#include <regex>
#include <sys/wait.h>
#include <unistd.h>

using namespace cutload::test;

namespace {

// The pid in a claim token ("host:pid:random/seq"); -1 for none.
pid_t pid_of_token(const std::string& token) {
    static const std::regex re(R"(^[^:]*:(\d+):[0-9a-f]+/\d+$)");
    std::smatch m;
    return std::regex_match(token, m, re) ? static_cast<pid_t>(std::stol(m[1])) : -1;
}

struct Workers {
    std::vector<std::string> args;
    fs::path dir;
    std::vector<pid_t> pids;
    std::vector<fs::path> logs;   // every generation's log: the kills must not lose their lines

    void start(std::size_t slot) {
        const fs::path log = dir / ("worker-" + std::to_string(slot) + "-" + std::to_string(logs.size()) + ".log");
        logs.push_back(log);
        pids.at(slot) = spawn(args, log);
    }
    std::string all_logs() const {
        std::string out;
        for (const auto& l : logs) out += read_text(l);
        return out;
    }
};

// An API-only server (--workers 0) on a fresh PostgreSQL database, with an admin key and the
// shared uploads folder the workers are given.
struct ApiOnly {
    explicit ApiOnly(const std::string& name, double lease_s = 30) {
        db = store_location(dir.path(), name);
        data = dir.path() / "data";
        fs::create_directories(data);
        cutload::server::ServerOptions opt;
        opt.port = 0;
        opt.db_path = db;
        opt.data_dir = data.string();
        opt.workers = 0;
        opt.lease_s = lease_s;
        key = cutload::server::create_api_key(db, cutload::server::Role::Admin, "workers test");
        server = std::make_unique<cutload::server::Server>(opt);
        server->start();
    }
    httplib::Client client() const {
        httplib::Client c("127.0.0.1", server->port());
        c.set_bearer_token_auth(key.c_str());
        c.set_read_timeout(30, 0);
        return c;
    }
    TempDir dir;
    std::string db, key;
    fs::path data;
    std::unique_ptr<cutload::server::Server> server;
};

}  // namespace

TEST_CASE("workers: three worker processes drain 18 runs while a computing worker is killed with kill -9 and another stalls past its lease, each run stored once") {
    if (!on_postgres()) {
        WARN("PostgreSQL only: cutload worker needs a store several processes share");
        return;
    }
    // The API only: this server computes nothing.
    ApiOnly api("workers.db", 1);
    const std::string& db = api.db;
    const fs::path& data = api.data;
    httplib::Client c = api.client();

    constexpr int kRuns = 18;
    std::vector<int> ids;
    // Each run computes for a few tenths of a second: long enough to be caught at it.
    json spec = slot_spec();
    spec["resolution"] = {{"angle_step_deg", 1.0}, {"axial_step_mm", 0.2}, {"grid_mm", 0.2}};
    for (int i = 0; i < kRuns; ++i) {
        auto r = upload(c, slot_log_csv(1.0 + 0.05 * i), spec);
        REQUIRE(r);
        INFO(r->body);
        REQUIRE(r->status == 202);
        ids.push_back(body(r)["id"]);
    }
    // Queued, and nobody computes them yet.
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    Sql sql(db);
    REQUIRE(sql.text("SELECT count(*) FROM runs WHERE state = 'queued'") == std::to_string(kRuns));

    Workers w;
    w.dir = api.dir.path();
    w.args = {CUTLOAD_BINARY, "worker", "--db", db, "--data-dir", data.string(), "--device", "cpu", "--lease-s", "1",
              "--drain-s", "0"};
    w.pids.assign(3, -1);
    for (std::size_t k = 0; k < 3; ++k) w.start(k);

    // The worker computing the oldest running run: its pid is in the claim token. With
    // `unlocked`, the oldest whose row no storing transaction holds.
    const auto computing = [&](bool unlocked = false) -> std::pair<std::size_t, std::string> {
        for (int tries = 0; tries < 2000; ++tries) {
            const std::string row = sql.text(
                "SELECT id || ' ' || claim_token FROM runs WHERE state = 'running' AND claim_token IS NOT NULL ORDER BY id "
                "LIMIT 1" + std::string(unlocked ? " FOR UPDATE SKIP LOCKED" : ""));
            if (!row.empty()) {
                const std::string run = row.substr(0, row.find(' '));
                const pid_t pid = pid_of_token(row.substr(row.find(' ') + 1));
                for (std::size_t k = 0; k < w.pids.size(); ++k)
                    if (w.pids[k] == pid) return {k, run};
            }
            std::this_thread::sleep_for(std::chrono::milliseconds(5));
        }
        FAIL("no worker was seen computing a run");
        return {0, ""};
    };

    // kill -9 a computing worker until two runs were killed mid-computation, restarting it each time.
    std::vector<std::string> killed_runs;
    for (int round = 0; round < 8 && killed_runs.size() < 2; ++round) {
        const auto [slot, run] = computing();
        ::kill(w.pids[slot], SIGKILL);
        wait_exit(w.pids[slot]);
        // Finished in the moment between the look and the kill: not a killed run.
        if (sql.text("SELECT state FROM runs WHERE id = " + run) == "running") killed_runs.push_back(run);
        w.start(slot);
        std::this_thread::sleep_for(std::chrono::milliseconds(700));
    }
    // SIGSTOP another past its lease: the others re-queue its run and one of them stores it;
    // woken up, it finds its claim gone and stores nothing. Only a worker stopped while it computes
    // counts: one stopped inside its storing transaction holds the run's row locked, the re-queue
    // skips locked rows by design, and that worker rightly keeps and stores its run.
    std::string stalled_run;
    for (int round = 0; round < 20 && stalled_run.empty(); ++round) {
        const auto [slot, run] = computing(true);
        ::kill(w.pids[slot], SIGSTOP);
        // Finished in the moment between the look and the stop, or storing: try another.
        const bool computing_now =
            sql.text("SELECT state FROM runs WHERE id = " + run) == "running" &&
            sql.text("SELECT id FROM runs WHERE id = " + run + " FOR UPDATE SKIP LOCKED") == run;
        if (computing_now) {
            std::this_thread::sleep_for(std::chrono::milliseconds(3000));
            // Its lease (1 s) ended and another claim took the run.
            if (std::stoi(sql.text("SELECT attempts FROM runs WHERE id = " + run)) >= 2) stalled_run = run;
        }
        ::kill(w.pids[slot], SIGCONT);
        // Let a worker caught storing finish before the next look.
        if (stalled_run.empty()) std::this_thread::sleep_for(std::chrono::milliseconds(200));
    }
    REQUIRE_FALSE(stalled_run.empty());

    // Drained: every run done.
    const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(150);
    while (sql.text("SELECT count(*) FROM runs WHERE state = 'done'") != std::to_string(kRuns)) {
        INFO(sql.text("SELECT string_agg(id || ':' || state, ' ') FROM runs"));
        if (std::chrono::steady_clock::now() > until) {
            INFO(w.all_logs());
            FAIL("runs not drained within 150 s");
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    // The stalled worker lets go of its run at its next lease check or when it tries to store it;
    // the others can drain the queue before either (their runs take under a second), so it is
    // given the time before the workers are stopped.
    auto let_go_logged = [&] {
        const std::string l = w.all_logs();
        return l.find("no longer holds its claim") != std::string::npos ||
               l.find("no longer held by this claim") != std::string::npos;
    };
    const auto let_go_until = std::chrono::steady_clock::now() + std::chrono::seconds(60);
    while (!let_go_logged() && std::chrono::steady_clock::now() < let_go_until)
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
    for (std::size_t k = 0; k < 3; ++k) {
        ::kill(w.pids[k], SIGTERM);
        const int status = wait_exit(w.pids[k]);
        INFO("worker " << k << ": " << read_text(w.logs.back()));
        REQUIRE(WIFEXITED(status));
        REQUIRE(WEXITSTATUS(status) == 0);
    }
    const std::string logs = w.all_logs();
    INFO(logs);

    // Each run stored once: one set of blocks, and at most one "done" line over all the workers'
    // logs (none when a kill landed between a worker's commit and its log line).
    std::map<int, int> done_lines;
    static const std::regex done_re(R"(run (\d+) done in)");
    for (auto it = std::sregex_iterator(logs.begin(), logs.end(), done_re); it != std::sregex_iterator(); ++it)
        ++done_lines[std::stoi((*it)[1])];
    for (const int id : ids) {
        INFO("run " << id);
        REQUIRE(done_lines[id] <= 1);
        json run = body(c.Get(("/api/v1/runs/" + std::to_string(id)).c_str()));
        REQUIRE(run["state"] == "done");
        REQUIRE(run["error"].is_null());
        REQUIRE(body(c.Get(("/api/v1/runs/" + std::to_string(id) + "/blocks").c_str()))["items"].size() == 2);
    }
    REQUIRE(done_lines.size() + killed_runs.size() + 1 >= static_cast<std::size_t>(kRuns));
    REQUIRE(killed_runs.size() == 2);
    // The killed workers' runs were claimed again after their leases ended. (Which process
    // re-queued them, a worker or the API server's own pool, is not fixed: the store says it.)
    for (const auto& run : killed_runs) {
        INFO("killed run " << run);
        REQUIRE(std::stoi(sql.text("SELECT attempts FROM runs WHERE id = " + run)) >= 2);
    }
    // The stalled worker let go of its run: another claim stored it.
    REQUIRE(std::stoi(sql.text("SELECT attempts FROM runs WHERE id = " + stalled_run)) >= 2);
    REQUIRE(let_go_logged());
    api.server->stop();
}

TEST_CASE("workers: cutload worker refuses an SQLite store and a missing data folder with one line each") {
    TempDir dir;
    const fs::path out = dir.path() / "worker.out";
    const fs::path sqlite_db = dir.path() / "one.db";
    pid_t p = spawn({CUTLOAD_BINARY, "worker", "--db", sqlite_db.string(), "--data-dir", dir.path().string()}, out);
    const int status = wait_exit(p);
    REQUIRE(WIFEXITED(status));
    REQUIRE(WEXITSTATUS(status) != 0);
    const std::string text = read_text(out);
    INFO(text);
    REQUIRE(text.find("a worker needs a store other processes share") != std::string::npos);
    REQUIRE(std::count(text.begin(), text.end(), '\n') == 1);
    REQUIRE_FALSE(fs::exists(sqlite_db));   // refused before anything is created

    const fs::path out2 = dir.path() / "worker2.out";
    p = spawn({CUTLOAD_BINARY, "worker", "--db", "postgresql://nobody@127.0.0.1:1/none", "--data-dir",
               (dir.path() / "missing").string()},
              out2);
    const int status2 = wait_exit(p);
    REQUIRE(WEXITSTATUS(status2) != 0);
    INFO(read_text(out2));
    REQUIRE(read_text(out2).find("--data-dir") != std::string::npos);
}

TEST_CASE("workers: a cancel through an API-only server stops the run a worker computes, and the worker answers /metrics") {
    if (!on_postgres()) {
        WARN("PostgreSQL only: cutload worker needs a store several processes share");
        return;
    }
    ApiOnly api("cancel.db");
    const std::string& db = api.db;
    const fs::path& data = api.data;
    httplib::Client c = api.client();

    const fs::path log = api.dir.path() / "worker.log";
    const pid_t worker = spawn({CUTLOAD_BINARY, "worker", "--db", db, "--data-dir", data.string(), "--device", "cpu",
                                "--lease-s", "1.5", "--metrics-listen", "127.0.0.1:0"},
                               log);
    int metrics_port = 0;
    static const std::regex listening(R"(metrics on http://127\.0\.0\.1:(\d+)/metrics)");
    for (int i = 0; i < 500 && metrics_port == 0; ++i) {
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
        const std::string out = read_text(log);
        std::smatch m;
        if (std::regex_search(out, m, listening)) metrics_port = std::stoi(m[1]);
    }
    INFO(read_text(log));
    REQUIRE(metrics_port > 0);

    // A run long enough to be cancelled mid-computation (a fine step over 30 s of log).
    json spec = slot_spec();
    spec["resolution"] = {{"angle_step_deg", 0.25}, {"axial_step_mm", 0.05}, {"grid_mm", 0.1}};
    const int id = body(upload(c, slot_log_csv(30.0), spec))["id"];
    json run;
    for (int i = 0; i < 2000; ++i) {
        run = body(c.Get(("/api/v1/runs/" + std::to_string(id)).c_str()));
        if (run["state"] == "running" && run["progress"].get<double>() > 0) break;
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    REQUIRE(run["state"] == "running");
    // This server computes nothing: the cancel goes through the store to the worker.
    auto r = c.Post(("/api/v1/runs/" + std::to_string(id) + "/cancel").c_str(), "", "application/json");
    REQUIRE(r);
    INFO(r->body);
    REQUIRE(r->status == 202);
    REQUIRE(body(c.Get(("/api/v1/runs/" + std::to_string(id)).c_str()))["state"] == "cancelled");
    // The worker stops within a renewal (0.5 s) plus a cancel check.
    bool stopped = false;
    for (int i = 0; i < 500 && !stopped; ++i) {
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
        stopped = read_text(log).find("its claim is gone") != std::string::npos;
    }
    INFO(read_text(log));
    REQUIRE(stopped);
    REQUIRE(body(c.Get(("/api/v1/runs/" + std::to_string(id)).c_str()))["state"] == "cancelled");

    // The worker's own metrics and health, without a key.
    httplib::Client m("127.0.0.1", metrics_port);
    std::string text;
    for (int i = 0; i < 100; ++i) {   // the job leaves the worker's count just after its log line
        auto metrics = m.Get("/metrics");
        REQUIRE(metrics);
        REQUIRE(metrics->status == 200);
        text = metrics->body;
        if (text.find("cutload_jobs_running 0") != std::string::npos) break;
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    INFO(text);
    REQUIRE(text.find("cutload_jobs_queued 0") != std::string::npos);
    REQUIRE(text.find("cutload_jobs_running 0") != std::string::npos);
    REQUIRE(text.find("# TYPE cutload_jobs_total counter") != std::string::npos);
    auto health = m.Get("/healthz");
    REQUIRE(health);
    REQUIRE(json::parse(health->body)["role"] == "worker");
    ::kill(worker, SIGTERM);
    REQUIRE(WEXITSTATUS(wait_exit(worker)) == 0);
    api.server->stop();
}
