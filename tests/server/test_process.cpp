// The real binary: `cutload keys create`, kill -9 in the middle of a job and restart (the job
// runs again to completion, nothing half-written), SIGTERM re-queues and exits promptly.
#include "harness.hpp"
#include "spawn.hpp"

#include <algorithm>
#include <csignal>
#include <fcntl.h>
#include <regex>
#include <sys/wait.h>
#include <unistd.h>

using namespace cutload::test;

namespace {

// A run long enough to be caught mid-job: a finer angle step makes each logged second dear.
json slow_spec() {
    json s = slot_spec();
    s["resolution"] = {{"angle_step_deg", 0.5}, {"axial_step_mm", 0.1}, {"grid_mm", 0.1}};
    return s;
}

json get_run(httplib::Client& c, int id) { return body(c.Get(("/api/v1/runs/" + std::to_string(id)).c_str())); }

}  // namespace

TEST_CASE("process: kill -9 mid-job then restart completes queued and running jobs with results written once") {
    TempDir dir;
    const fs::path db = store_location(dir.path(), "k.db");
    const fs::path log = dir.path() / "serve.log";
    const fs::path keys_out = dir.path() / "keys.out";
    pid_t kp = spawn({CUTLOAD_BINARY, "keys", "create", "--role", "admin", "--db", db.string()}, keys_out);
    REQUIRE(WEXITSTATUS(wait_exit(kp)) == 0);
    std::string out = read_text(keys_out);
    out.erase(out.find_last_not_of('\n') + 1);
    const std::string key = out.substr(out.rfind('\n') + 1);   // the key is the last line
    REQUIRE(key.rfind("clk_", 0) == 0);

    Proc p = start_server(db, log);
    httplib::Client c("127.0.0.1", p.port);
    c.set_bearer_token_auth(key.c_str());
    std::vector<int> ids;
    for (int i = 0; i < 2; ++i) {
        auto r = upload(c, slot_log_csv(i == 0 ? 4.0 : 0.5), slow_spec());
        REQUIRE(r->status == 202);
        ids.push_back(body(r)["id"]);
    }
    // Wait until the first job is computing, then kill without warning.
    for (int i = 0; i < 1000; ++i) {
        json run = get_run(c, ids[0]);
        if (run["state"] == "running" && run["progress"].get<double>() > 0) break;
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    REQUIRE(get_run(c, ids[0])["state"] == "running");
    ::kill(p.pid, SIGKILL);
    wait_exit(p.pid);

    Proc p2 = start_server(db, log);
    httplib::Client c2("127.0.0.1", p2.port);
    c2.set_bearer_token_auth(key.c_str());
    for (int id : ids) {
        json run = wait_finished(c2, id, 60);
        REQUIRE(run["state"] == "done");
        REQUIRE(run["error"].is_null());
    }
    json first = get_run(c2, ids[0]);
    REQUIRE(first["attempts"] == 2);
    json blocks = body(c2.Get(("/api/v1/runs/" + std::to_string(ids[0]) + "/blocks").c_str()));
    REQUIRE(blocks["items"].size() == 2);   // one set of results, not two
    REQUIRE(body(c2.Get(("/api/v1/runs/" + std::to_string(ids[0]) + "/forces?max_points=20000&from_s=0&to_s=0.5").c_str()))["count"].get<int>() > 0);
    ::kill(p2.pid, SIGTERM);
    REQUIRE(WEXITSTATUS(wait_exit(p2.pid)) == 0);
}

TEST_CASE("process: SIGTERM stops promptly and re-queues the running job and a restart finishes it") {
    TempDir dir;
    const fs::path db = store_location(dir.path(), "t.db");
    const fs::path log = dir.path() / "serve.log";
    const std::string key = cutload::server::create_api_key(db.string(), cutload::server::Role::Write);
    Proc p = start_server(db, log);
    httplib::Client c("127.0.0.1", p.port);
    c.set_bearer_token_auth(key.c_str());
    auto r = upload(c, slot_log_csv(4.0), slow_spec());
    const int id = body(r)["id"];
    for (int i = 0; i < 1000 && get_run(c, id)["state"] != "running"; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(5));
    const auto t0 = std::chrono::steady_clock::now();
    ::kill(p.pid, SIGTERM);
    REQUIRE(WEXITSTATUS(wait_exit(p.pid)) == 0);
    const double stop_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    REQUIRE(stop_s < 3);
    INFO(read_text(log));
    REQUIRE(read_text(log).find("re-queued") != std::string::npos);
    WARN("SIGTERM with --drain-s 0 and a run mid-prediction: the process exited " << stop_s * 1000 << " ms after the signal");

    Proc p2 = start_server(db, log);
    httplib::Client c2("127.0.0.1", p2.port);
    c2.set_bearer_token_auth(key.c_str());
    const json done = wait_finished(c2, id, 60);
    REQUIRE(done["state"] == "done");
    // A graceful stop gave its claim back: only the restart's claim counts toward --max-attempts.
    REQUIRE(done["attempts"] == 1);
    ::kill(p2.pid, SIGTERM);
    wait_exit(p2.pid);
}

TEST_CASE("process: a run that kill -9 interrupts at every attempt ends failed at the attempt cap, with the reason") {
    // Issue 19: the re-queue after a crash had no cap, so a job that took the server down did it
    // again at every restart.
    TempDir dir;
    const fs::path db = store_location(dir.path(), "loop.db");
    const fs::path log = dir.path() / "serve.log";
    const std::string key = cutload::server::create_api_key(db.string(), cutload::server::Role::Write);
    const std::vector<std::string> cap{"--max-attempts", "2"};
    Proc p = start_server(db, log, cap);
    int id = 0;
    for (int attempt = 1; attempt <= 2; ++attempt) {
        httplib::Client c("127.0.0.1", p.port);
        c.set_bearer_token_auth(key.c_str());
        if (attempt == 1) id = body(upload(c, slot_log_csv(4.0), slow_spec()))["id"];
        // Claimed by this server (on PostgreSQL the dead one's claim shows 'running' until its
        // lease ends and the run is claimed again).
        const auto claimed = [&] {
            const json r = get_run(c, id);
            return r["state"] == "running" && r["attempts"] == attempt;
        };
        for (int i = 0; i < 2000 && !claimed(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(5));
        json run = get_run(c, id);
        REQUIRE(run["state"] == "running");
        REQUIRE(run["attempts"] == attempt);
        ::kill(p.pid, SIGKILL);
        wait_exit(p.pid);
        p = start_server(db, log, cap);
    }
    httplib::Client c("127.0.0.1", p.port);
    c.set_bearer_token_auth(key.c_str());
    // SQLite: failed at the restart. PostgreSQL: once the dead process's lease ends.
    const json run = wait_finished(c, id, 20);
    INFO(run.dump());
    REQUIRE(run["state"] == "failed");
    REQUIRE(run["attempts"] == 2);
    REQUIRE(run["error"].get<std::string>().find("interrupted 2 times") != std::string::npos);
    // The server stays up and answers; a new run is computed.
    const int next = body(upload(c, slot_log_csv(0.3), slot_spec()))["id"];
    REQUIRE(wait_finished(c, next, 60)["state"] == "done");
    ::kill(p.pid, SIGTERM);
    REQUIRE(WEXITSTATUS(wait_exit(p.pid)) == 0);
}

TEST_CASE("process: SIGTERM gives a running job --drain-s seconds, then re-queues it and exits") {
    TempDir dir;
    const fs::path db = store_location(dir.path(), "d.db");
    const fs::path log = dir.path() / "serve.log";
    const std::string key = cutload::server::create_api_key(db.string(), cutload::server::Role::Write);
    constexpr double kDrainS = 1.0;
    Proc p = start_server(db, log, {"--drain-s", "1"});
    httplib::Client c("127.0.0.1", p.port);
    c.set_bearer_token_auth(key.c_str());
    // Computes for far longer than the drain: 4 s of motion took 1.4 s on PoCL with two idle cores,
    // which a job already under way when the signal came could finish within its drain.
    const int id = body(upload(c, slot_log_csv(16.0), slow_spec()))["id"];
    for (int i = 0; i < 2000; ++i) {
        const json run = get_run(c, id);
        if (run["state"] == "running" && run["progress"].get<double>() > 0) break;
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    REQUIRE(get_run(c, id)["state"] == "running");
    const auto t0 = std::chrono::steady_clock::now();
    ::kill(p.pid, SIGTERM);
    REQUIRE(WEXITSTATUS(wait_exit(p.pid)) == 0);
    const double stop_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    INFO(read_text(log));
    // The job had its drain (it did not stop at once) and no more than a cancel check beyond it.
    REQUIRE(stop_s >= kDrainS);
    REQUIRE(stop_s < kDrainS + 2);
    REQUIRE(read_text(log).find("re-queued") != std::string::npos);
    WARN("SIGTERM with --drain-s 1 and a run mid-prediction: the process exited " << stop_s * 1000 << " ms after the signal");
}
