// The job registry: a kind is one registration (its queue, its handler, its metric names) and the
// pool claims, dispatches, finishes, cancels, re-queues and counts it like the service's own kinds.
// Shown with two test-only kinds over tables of their own.
#include "db/store.hpp"
#include "harness.hpp"
#include "server/jobs.hpp"

#include <atomic>
#include <mutex>
#include <set>

using namespace cutload::test;
using cutload::server::JobContext;
using cutload::server::JobKind;

namespace {

// Test-only kinds have no repository: their handlers use the database directly (Sql, test_store.hpp).

// The job columns every queue table has (db/jobs.hpp), then the kind's own.
std::string job_table(const Sql& sql, const std::string& name, const std::string& own_columns) {
    return "CREATE TABLE " + name + " (" + sql.id_column() +
           ", state TEXT NOT NULL, progress DOUBLE PRECISION NOT NULL DEFAULT 0, error TEXT, "
           "attempts INTEGER NOT NULL DEFAULT 0, started_at TEXT, finished_at TEXT, claim_token TEXT, lease_until TEXT, " +
           own_columns + ");";
}

bool wait_for(const std::function<bool()>& done, double timeout_s = 20) {
    const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    while (!done()) {
        if (std::chrono::steady_clock::now() > until) return false;
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    return true;
}

}  // namespace

TEST_CASE("jobs: a test-only kind is one registration plus its handler, claimed in registry order, failed, cancelled, re-queued and counted") {
    TempDir dir;
    const std::string path = store_location(dir.path(), "jobs.db");
    auto store = cutload::db::Store::open(path);
    store->migrate();
    Sql sql(path);
    // Squares: x -> x2; the one at x = 13 fails. The running row was left by a server that died.
    sql.exec(job_table(sql, "squares", "x INTEGER NOT NULL, x2 INTEGER") +
             "INSERT INTO squares(state, x) VALUES ('queued', 3), ('queued', -4), ('queued', 13), ('running', 5);");
    // Waits: a job that computes until it is cancelled.
    sql.exec(job_table(sql, "waits", "note TEXT") + "INSERT INTO waits(state) VALUES ('queued'), ('queued');");

    std::mutex mu;
    std::vector<std::string> order;
    auto record = [&](const std::string& what) {
        std::lock_guard lk(mu);
        order.push_back(what);
    };
    JobKind square{"square", {"squares"}, {},
                   [&](JobContext& ctx) -> std::optional<std::string> {
                       record("square");
                       Sql own(path);
                       const long long x = std::stoll(own.text("SELECT x FROM squares WHERE id = " + std::to_string(ctx.id)));
                       if (x == 13) throw std::runtime_error("13 is not squared here");
                       ctx.progress(0.5);
                       // Results and state done in one statement, only while still running.
                       own.exec("UPDATE squares SET x2 = " + std::to_string(x * x) +
                                ", state = 'done', progress = 1 WHERE state = 'running' AND id = " + std::to_string(ctx.id));
                       return " (squared)";
                   },
                   {"cutload_squares_total", "Squares finished.", "cutload_squares_queued", "Squares waiting."}};
    JobKind wait{"wait", {"waits"}, {},
                 [&](JobContext& ctx) -> std::optional<std::string> {
                     record("wait");
                     while (!ctx.cancel) std::this_thread::sleep_for(std::chrono::milliseconds(5));
                     throw cutload::force_model::Cancelled();
                 },
                 {"cutload_waits_total", "Waits finished.", "cutload_waits_queued", "Waits waiting."}};

    cutload::server::Metrics metrics;
    cutload::server::Jobs jobs(*store, {1, 3}, metrics, {square, wait});
    jobs.start();
    jobs.notify();
    auto state_of = [&](const char* table, int id) {
        return sql.text(std::string("SELECT state FROM ") + table + " WHERE id = " + std::to_string(id));
    };
    // The squares go first (registry order), then the first wait starts and is cancelled.
    REQUIRE(wait_for([&] { return state_of("waits", 1) == "running"; }));
    REQUIRE(jobs.cancel_running({"waits"}, 1));
    REQUIRE_FALSE(jobs.cancel_running({"waits"}, 99));
    REQUIRE(wait_for([&] { return state_of("waits", 1) == "cancelled" && state_of("waits", 2) == "running"; }));
    // Stopping the server re-queues the one computing.
    jobs.stop(0);
    REQUIRE(state_of("waits", 2) == "queued");
    REQUIRE(sql.text("SELECT finished_at FROM waits WHERE id = 2").empty());
    // A graceful stop gives the claim back: attempts count only the crashes.
    REQUIRE(sql.text("SELECT attempts FROM waits WHERE id = 2") == "0");

    {
        std::lock_guard lk(mu);
        REQUIRE(order == std::vector<std::string>{"square", "square", "square", "square", "wait", "wait"});
    }
    for (const auto& [id, x] : std::vector<std::pair<int, long long>>{{1, 3}, {2, -4}, {4, 5}}) {
        INFO("square " << id);
        REQUIRE(state_of("squares", id) == "done");
        REQUIRE(sql.text("SELECT x2 FROM squares WHERE id = " + std::to_string(id)) == std::to_string(x * x));
        REQUIRE(sql.text("SELECT attempts FROM squares WHERE id = " + std::to_string(id)) == "1");
        REQUIRE_FALSE(sql.text("SELECT started_at FROM squares WHERE id = " + std::to_string(id)).empty());
    }
    REQUIRE(state_of("squares", 3) == "failed");
    REQUIRE(sql.text("SELECT error FROM squares WHERE id = 3") == "13 is not squared here");
    REQUIRE(sql.text("SELECT x2 FROM squares WHERE id = 3").empty());

    const std::string text =
        metrics.render({{&square.metrics, 0}, {&wait.metrics, 1}}, jobs.running(), 0);
    for (const char* line : {"# TYPE cutload_squares_total counter", "cutload_squares_total{state=\"done\"} 3",
                             "cutload_squares_total{state=\"failed\"} 1", "cutload_squares_total{state=\"cancelled\"} 0",
                             "cutload_waits_total{state=\"cancelled\"} 1", "cutload_waits_total{state=\"requeued\"} 1",
                             "cutload_waits_total{state=\"done\"} 0", "# TYPE cutload_waits_queued gauge",
                             "cutload_waits_queued 1", "cutload_jobs_running 0"}) {
        INFO(line << "\n" << text);
        REQUIRE(text.find(line) != std::string::npos);
    }
    // The queue operations every kind shares: a queued job is cancelled and counted by state.
    auto s = store->session();
    REQUIRE(s->jobs().count({"waits"}, {cutload::db::JobState::Queued}) == 1);
    REQUIRE(s->jobs().cancel_queued({"waits"}, 2, cutload::db::now_iso()));
    REQUIRE_FALSE(s->jobs().cancel_queued({"waits"}, 2, cutload::db::now_iso()));
    REQUIRE(s->jobs().count({"waits"}, {cutload::db::JobState::Cancelled, cutload::db::JobState::Queued}) == 2);
}

TEST_CASE("jobs: a job left running by servers that died is re-queued until the attempt cap, then failed with the reason") {
    TempDir dir;
    const std::string path = store_location(dir.path(), "jobs.db");
    auto store = cutload::db::Store::open(path);
    store->migrate();
    Sql sql(path);
    // Each 'running' row was claimed `attempts` times by servers that died (kill -9) mid-job.
    sql.exec(job_table(sql, "crashes", "note TEXT") +
             "INSERT INTO crashes(state, attempts) VALUES ('running', 1), ('running', 2), ('running', 3), ('queued', 0);");
    std::atomic<int> computed{0};
    JobKind crash{"crash", {"crashes"}, {},
                  [&](JobContext& ctx) -> std::optional<std::string> {
                      ++computed;
                      Sql own(path);
                      own.exec("UPDATE crashes SET state = 'done' WHERE state = 'running' AND id = " + std::to_string(ctx.id));
                      return "";
                  },
                  {"cutload_crashes_total", "Crashes finished.", "cutload_crashes_queued", "Crashes waiting."}};
    cutload::server::Metrics metrics;
    {
        cutload::server::Jobs jobs(*store, {1, 3}, metrics, {crash});
        jobs.start();
        jobs.notify();
        REQUIRE(wait_for([&] { return computed.load() == 3; }));
        jobs.stop(0);
    }
    auto row = [&](int id, const char* col) {
        return sql.text(std::string("SELECT ") + col + " FROM crashes WHERE id = " + std::to_string(id));
    };
    for (int id : {1, 2, 4}) {
        INFO("job " << id);
        REQUIRE(row(id, "state") == "done");
    }
    REQUIRE(row(2, "attempts") == "3");   // its third and last claim
    REQUIRE(row(3, "state") == "failed");
    REQUIRE(row(3, "attempts") == "3");
    REQUIRE_FALSE(row(3, "finished_at").empty());
    INFO(row(3, "error"));
    REQUIRE(row(3, "error").find("interrupted 3 times") != std::string::npos);
    REQUIRE(row(3, "error").find("--max-attempts 3") != std::string::npos);

    // The repository's contract, directly: a cap of 1 fails every job a dead server left.
    sql.exec("UPDATE crashes SET state = 'running', attempts = 1 WHERE id = 4");
    const auto r = store->session()->jobs().requeue_interrupted({"crashes"}, 1, "cap", cutload::db::now_iso());
    REQUIRE(r.failed == 1);
    REQUIRE(r.requeued == 0);
    REQUIRE(row(4, "error") == "cap");
}

TEST_CASE("jobs: job states have one text each, and text that is no state is refused") {
    using cutload::db::JobState;
    std::set<std::string> texts;
    for (const JobState s : cutload::db::job_states()) {
        const std::string t(cutload::db::to_text(s));
        texts.insert(t);
        REQUIRE(cutload::db::job_state_from_text(t) == s);
    }
    REQUIRE(texts == std::set<std::string>{"queued", "running", "done", "failed", "cancelled"});
    REQUIRE_THROWS_WITH(cutload::db::job_state_from_text("sleeping"), Catch::Contains("'sleeping' is not a job state"));
    REQUIRE_FALSE(cutload::db::parse_job_state("Done"));
}
