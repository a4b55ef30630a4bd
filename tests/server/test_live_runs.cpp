// Live runs in the service, on loopback with the replay adapter (live::ReplayAdapter, the engine
// of `cutload replay`): a run end to end against an upload of the same log, an adapter killed and
// restarted mid-run (the gap marked), an alert and its webhook delivered while the replay still
// runs, and `cutload serve` killed with -9 during a live run and restarted (the run closed, once).
#include "harness.hpp"
#include "spawn.hpp"

#include "live/replay.hpp"

#include <csignal>
#include <set>
#include <mutex>

using namespace cutload::test;
using namespace std::chrono_literals;

namespace {

std::string source_path(const std::string& rel) { return std::string(CUTLOAD_SOURCE_DIR) + "/" + rel; }

json demo_spec() {
    std::ifstream in(source_path("data/demo_run.json"));
    return json::parse(in);
}

fs::path write_file(const fs::path& p, const std::string& text) {
    std::ofstream out(p, std::ios::binary);
    out << text;
    return p;
}

// The demo log with its times moved so that its earliest reading is at 0, the run time a live run
// gives it (time 0 is its first observation). The upload it is compared with is timed the same
// way: the CNC clock recovery counts ticks from time 0, and a 3 ms shift of that origin alone
// moves the mean force of two demo blocks by 17-20 % (docs/live.md, "Agreement").
std::string demo_rezeroed_csv() {
    std::ifstream in(source_path("data/demo_dryrun.csv"));
    std::string header, line;
    std::getline(in, header);
    std::vector<std::vector<std::string>> rows;
    double t0 = 1e300;
    const std::size_t time_cols[] = {0, 2, 4};   // t_spindle, t_feed, t_pos
    while (std::getline(in, line)) {
        std::vector<std::string> f;
        std::stringstream ss(line);
        for (std::string x; std::getline(ss, x, ',');) f.push_back(x);
        for (std::size_t c : time_cols) t0 = std::min(t0, std::stod(f.at(c)));
        rows.push_back(std::move(f));
    }
    std::string out = header + "\n";
    char num[32];
    for (auto& f : rows) {
        for (std::size_t c : time_cols) {
            std::snprintf(num, sizeof num, "%.6f", std::stod(f[c]) - t0);
            f[c] = num;
        }
        for (std::size_t k = 0; k < f.size(); ++k) out += (k ? "," : "") + f[k];
        out += "\n";
    }
    return out;
}

// Until the run is neither queued, running nor live (the harness's wait_finished returns on live).
json wait_closed(httplib::Client& c, std::int64_t id, double timeout_s) {
    const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    for (;;) {
        const json run = body(c.Get(("/api/v1/runs/" + std::to_string(id)).c_str()));
        const std::string state = run["state"];
        if (state != "queued" && state != "running" && state != "live") return run;
        if (std::chrono::steady_clock::now() > until) FAIL("run " << id << " still " << state);
        std::this_thread::sleep_for(20ms);
    }
}

std::unique_ptr<cutload::live::ReplayAdapter> replay(const std::string& log, double speed, int port = 0) {
    cutload::live::ReplayOptions ro;
    ro.log = log;
    ro.port = port;
    ro.speed = speed;
    return std::make_unique<cutload::live::ReplayAdapter>(ro);
}

json start_live(httplib::Client& c, int port, const json& spec, double idle_s) {
    const json req{{"source", {{"adapter", "127.0.0.1:" + std::to_string(port)}}},
                   {"spec", spec},
                   {"sampling", "polled"},
                   {"clock_batch_readings", 1024},
                   {"idle_timeout_s", idle_s},
                   {"name", "live test"}};
    auto r = c.Post("/api/v1/live", req.dump(), "application/json");
    REQUIRE(r);
    INFO(r->body);
    REQUIRE(r->status == 201);
    return json::parse(r->body);
}

std::string fmt_path(std::int64_t id, std::int64_t after, std::int64_t from_block) {
    return "/api/v1/live/" + std::to_string(id) + "?after=" + std::to_string(after) + "&from_block=" + std::to_string(from_block) +
           "&max_points=20000";
}

// Polls the live view until the run closes, gathering its rows and blocks through the cursors.
struct Followed {
    std::vector<double> t_s, force_N;
    json blocks = json::array();
    std::set<std::string> connections;
    bool saw_live_state = false;
};

Followed follow(httplib::Client& c, std::int64_t id, double timeout_s) {
    Followed f;
    std::int64_t after = 0, from_block = 0;
    const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    for (;;) {
        const json run = body(c.Get(("/api/v1/runs/" + std::to_string(id)).c_str()));
        if (run["state"] == "live") f.saw_live_state = true;
        const json v = body(c.Get(fmt_path(id, after, from_block).c_str()));
        for (std::size_t i = 0; i < v["forces"]["t_s"].size(); ++i) {
            f.t_s.push_back(v["forces"]["t_s"][i]);
            f.force_N.push_back(v["forces"]["force_N"][i]);
        }
        for (const auto& b : v["blocks"]) f.blocks.push_back(b);
        f.connections.insert(v["connection"].get<std::string>());
        after = v["next_after"];
        from_block = v["next_block"];
        if (v["state"] == "closed" && !v["more"].get<bool>()) return f;
        if (std::chrono::steady_clock::now() > until) FAIL("live run " << id << " still open");
        std::this_thread::sleep_for(50ms);
    }
}

}  // namespace

TEST_CASE("live runs: the demo replayed at 10x is followed live and stored like an upload of the log", "[live]") {
    TestServer ts;
    auto c = ts.admin();
    auto adapter = replay(source_path("data/demo_dryrun.csv"), 10);
    const json started = start_live(c, adapter->port(), demo_spec(), 1.0);
    const std::int64_t id = started["id"];
    REQUIRE(started["state"] == "live");
    const Followed f = follow(c, id, 60);
    CHECK(f.saw_live_state);
    CHECK(f.connections.count("connected") == 1);
    REQUIRE(f.blocks.size() > 10);   // blocks came while it ran
    REQUIRE(f.t_s.size() > 1000);

    const json run = wait_closed(c, id, 30);
    REQUIRE(run["state"] == "done");
    CHECK(run["summary"]["live"]["end"] == "idle");
    CHECK(run["summary"]["live"]["gaps"].empty());
    CHECK(run["inputs"]["live"]["source"] == "shdr://127.0.0.1:" + std::to_string(adapter->port()));

    // The same log uploaded (timed from its first reading, as the live run times it): the same
    // blocks, peaks, means and removed volumes within 1 %, the same flags.
    auto up = c.Post("/api/v1/runs",
                     httplib::MultipartFormDataItems{{"log", demo_rezeroed_csv(), "demo.csv", "text/csv"},
                                                     {"spec", demo_spec().dump(), "", "application/json"}});
    REQUIRE(up->status == 202);
    const json offline = wait_finished(c, body(up)["id"], 120);
    REQUIRE(offline["state"] == "done");
    const json& a = offline["summary"];
    const json& b = run["summary"];
    CHECK(b["peak_force_N"].get<double>() == Approx(a["peak_force_N"].get<double>()).epsilon(0.01));
    CHECK(b["blocks"] == a["blocks"]);
    CHECK(b["flags"] == a["flags"]);
    CHECK(b["flagged_blocks"] == a["flagged_blocks"]);
    CHECK(b["removed_mm3"].get<double>() == Approx(a["removed_mm3"].get<double>()).epsilon(0.01));
    const json blocks_live = body(c.Get(("/api/v1/runs/" + std::to_string(id) + "/blocks").c_str()))["items"];
    const json blocks_off = body(c.Get(("/api/v1/runs/" + offline["id"].dump() + "/blocks").c_str()))["items"];
    REQUIRE(blocks_live.size() == blocks_off.size());
    for (std::size_t i = 0; i < blocks_off.size(); ++i) {
        INFO("block " << blocks_off[i]["block"]);
        CHECK(blocks_live[i]["block"] == blocks_off[i]["block"]);
        const double peak_N = a["peak_force_N"].get<double>();
        for (const char* key : {"peak_force_N", "mean_force_N"})
            CHECK(blocks_live[i][key].get<double>() ==
                  Approx(blocks_off[i][key].get<double>()).epsilon(0.01).margin(0.01 * peak_N));
        CHECK(blocks_live[i]["removed_mm3"].get<double>() ==
              Approx(blocks_off[i]["removed_mm3"].get<double>()).epsilon(0.01).margin(1.0));
        CHECK(blocks_live[i]["t_start_s"].get<double>() == Approx(blocks_off[i]["t_start_s"].get<double>()).margin(1e-6));
        CHECK(blocks_live[i]["t_end_s"].get<double>() == Approx(blocks_off[i]["t_end_s"].get<double>()).margin(1e-6));
        CHECK(blocks_live[i]["flags"].size() == blocks_off[i]["flags"].size());
    }
    // The live view showed the blocks as the stored run has them.
    for (std::size_t i = 0; i < f.blocks.size(); ++i) CHECK(f.blocks[i]["block"] == blocks_live[i]["block"]);
    // The stored run is a normal one: its forces and its stock are there.
    CHECK(body(c.Get(("/api/v1/runs/" + std::to_string(id) + "/forces?max_points=100").c_str()))["count"].get<int>() > 0);
    // Closed: a second stop is a conflict, an unknown id is 404.
    require_error(c.Post(("/api/v1/live/" + std::to_string(id) + "/stop").c_str(), "", "application/json"), 409, "not_live");
    require_error(c.Get("/api/v1/live/99999"), 404, "not_found");
}

TEST_CASE("live runs: bad requests name the key", "[live]") {
    TestServer ts;
    auto c = ts.admin();
    auto post = [&](const json& j) { return c.Post("/api/v1/live", j.dump(), "application/json"); };
    require_error(post({{"spec", slot_spec()}}), 400, "bad_request", "source");
    require_error(post({{"source", {{"adapter", "127.0.0.1:99999"}}}, {"spec", slot_spec()}}), 400, "bad_request", "source.adapter");
    require_error(post({{"source", "ftp://x"}, {"spec", slot_spec()}}), 400, "bad_request", "source");
    require_error(post({{"source", {{"adapter", "127.0.0.1:7878"}}}}), 400, "bad_spec", "spec");
    json bad = slot_spec();
    bad["tool"]["diameter_mm"] = -1;
    require_error(post({{"source", {{"adapter", "127.0.0.1:7878"}}}, {"spec", bad}}), 400, "bad_spec", "diameter_mm");
    require_error(post({{"source", {{"adapter", "127.0.0.1:7878"}}}, {"spec", slot_spec()}, {"sampling", "often"}}), 400,
                  "bad_request", "sampling");
    require_error(post({{"source", {{"adapter", "127.0.0.1:7878"}}}, {"spec", slot_spec()}, {"idle_timeout_s", -1}}), 400,
                  "bad_request", "idle_timeout_s");
    require_error(post({{"source", {{"adapter", "127.0.0.1:7878"}}}, {"spec", slot_spec()}, {"key_map", {{"position", 3}}}}),
                  400, "bad_request", "key_map");
}

TEST_CASE("live runs: an adapter killed and restarted mid-run resumes the run and marks the gap", "[live]") {
    TestServer ts;
    auto c = ts.admin();
    TempDir dir;
    // 6 s at 1x: the first rows come once the clock recovery has a batch of readings (about a
    // second of this log), so the adapter dies well before the log's end.
    const std::string log = write_file(dir.path() / "slot.csv", slot_log_csv(6.0)).string();
    auto adapter = replay(log, 1);
    const int port = adapter->port();
    const std::int64_t id = start_live(c, port, slot_spec(), 1.5)["id"];
    // Some rows stored, then the adapter dies.
    for (int i = 0; i < 200; ++i) {
        const json v = body(c.Get(("/api/v1/live/" + std::to_string(id)).c_str()));
        if (v["rows"].get<int>() > 100) break;
        std::this_thread::sleep_for(20ms);
    }
    adapter.reset();
    std::string connection;
    for (int i = 0; i < 150 && connection != "disconnected"; ++i) {
        std::this_thread::sleep_for(20ms);
        connection = body(c.Get(("/api/v1/live/" + std::to_string(id)).c_str()))["connection"];
    }
    CHECK(connection == "disconnected");
    adapter = replay(log, 1, port);   // the machine's adapter back on its port
    const json run = wait_closed(c, id, 60);
    REQUIRE(run["state"] == "done");
    const json gaps = run["summary"]["live"]["gaps"];
    REQUIRE(gaps.size() == 1);
    CHECK(gaps[0]["gap_s"].get<double>() > 0.2);
    CHECK(run["summary"]["samples"].get<int>() > 0);
    CHECK(run["summary"]["live"]["end"] == "idle");
}

TEST_CASE("live runs: an alert is raised and its webhook delivered while the replay still runs", "[live]") {
    TestServer ts;
    auto c = ts.admin();
    std::mutex mu;
    std::vector<std::string> received;
    httplib::Server hook;
    hook.Post("/hook", [&](const httplib::Request& req, httplib::Response& res) {
        std::lock_guard lk(mu);
        received.push_back(req.body);
        res.status = 204;
    });
    const int hook_port = hook.bind_to_any_port("127.0.0.1");
    std::thread hook_thread([&] { hook.listen_after_bind(); });
    REQUIRE(c.Post("/api/v1/webhooks", json{{"url", "http://127.0.0.1:" + std::to_string(hook_port) + "/hook"}}.dump(),
                   "application/json")->status == 201);
    REQUIRE(c.Post("/api/v1/thresholds",
                   json{{"name", "force over 20 N"}, {"metric", "peak_force_N"}, {"limit", 20}}.dump(), "application/json")
                ->status == 201);
    TempDir dir;
    // 4 s at 1x: block N10 for 2 s, then N20. N10's alert must be out before N20 ends.
    auto adapter = replay(write_file(dir.path() / "slot.csv", slot_log_csv(4.0)).string(), 1);
    const std::int64_t id = start_live(c, adapter->port(), slot_spec(), 1.0)["id"];
    bool delivered_while_running = false;
    const auto until = std::chrono::steady_clock::now() + 20s;
    while (std::chrono::steady_clock::now() < until) {
        {
            std::lock_guard lk(mu);
            if (!received.empty()) {
                delivered_while_running = !adapter->stats().finished;
                break;
            }
        }
        std::this_thread::sleep_for(10ms);
    }
    CHECK(delivered_while_running);
    {
        std::lock_guard lk(mu);
        REQUIRE(!received.empty());
        const json payload = json::parse(received.front());
        CHECK(payload["event"] == "alert.raised");
        CHECK(payload["alert"]["run_id"] == id);
        CHECK(payload["alert"]["blocks"][0]["block"] == "N10");
    }
    const json run = wait_closed(c, id, 30);
    REQUIRE(run["state"] == "done");
    // One alert per block that tripped, raised as each ended, none again at the close.
    const json alerts = body(c.Get(("/api/v1/alerts?run_id=" + std::to_string(id)).c_str()))["items"];
    CHECK(alerts.size() == 2);
    CHECK(run["summary"]["alerts"] == 2);
    hook.stop();
    hook_thread.join();
}

TEST_CASE("live runs: cutload serve killed with -9 during a live run closes it once on restart", "[live]") {
    TempDir dir;
    const fs::path db = store_location(dir.path(), "k.db");
    const fs::path out = dir.path() / "serve.log";
    const fs::path keys_out = dir.path() / "keys.out";
    pid_t kp = spawn({CUTLOAD_BINARY, "keys", "create", "--role", "admin", "--db", db.string()}, keys_out);
    REQUIRE(WEXITSTATUS(wait_exit(kp)) == 0);
    std::string text = read_text(keys_out);
    text.erase(text.find_last_not_of('\n') + 1);
    const std::string key = text.substr(text.rfind('\n') + 1);

    auto adapter = replay(write_file(dir.path() / "slot.csv", slot_log_csv(6.0)).string(), 1);
    Proc p = start_server(db, out);
    httplib::Client c("127.0.0.1", p.port);
    c.set_bearer_token_auth(key.c_str());
    const std::int64_t id = start_live(c, adapter->port(), slot_spec(), 1.0)["id"];
    // Past the first block (N10 ends at 3 s), so blocks and rows are stored.
    json v;
    for (int i = 0; i < 400; ++i) {
        v = body(c.Get(("/api/v1/live/" + std::to_string(id) + "?max_points=10").c_str()));
        if (!v["blocks"].empty()) break;
        std::this_thread::sleep_for(20ms);
    }
    REQUIRE(v["blocks"].size() == 1);
    ::kill(p.pid, SIGKILL);
    wait_exit(p.pid);

    Proc p2 = start_server(db, out);
    httplib::Client c2("127.0.0.1", p2.port);
    c2.set_bearer_token_auth(key.c_str());
    const json run = body(c2.Get(("/api/v1/runs/" + std::to_string(id)).c_str()));
    REQUIRE(run["state"] == "done");   // closed at start-up, before anything could re-queue it
    CHECK(run["attempts"] == 1);
    CHECK(run["summary"]["live"]["end"] == "service_restart");
    const json gaps = run["summary"]["live"]["gaps"];
    REQUIRE(gaps.size() == 1);
    CHECK(gaps[0]["message"].get<std::string>().find("service stopped") != std::string::npos);
    const json blocks = body(c2.Get(("/api/v1/runs/" + std::to_string(id) + "/blocks").c_str()))["items"];
    REQUIRE(blocks.size() >= 1);   // what was stored, once
    CHECK(blocks[0]["block"] == "N10");
    CHECK(run["summary"]["samples"].get<int>() > 0);
    require_error(c2.Post(("/api/v1/live/" + std::to_string(id) + "/stop").c_str(), "", "application/json"), 409, "not_live");
    ::kill(p2.pid, SIGTERM);
    REQUIRE(WEXITSTATUS(wait_exit(p2.pid)) == 0);
}

TEST_CASE("live runs: a request naming a machine and no source follows the machine's live_source", "[live]") {
    TestServer ts;
    auto c = ts.admin();
    TempDir dir;
    const std::string log = write_file(dir.path() / "slot.csv", slot_log_csv(2.0)).string();
    auto adapter = replay(log, 4);
    const std::string address = "127.0.0.1:" + std::to_string(adapter->port());
    auto post_machine = [&](const json& j) { return c.Post("/api/v1/machines", j.dump(), "application/json"); };
    const json machine{{"spindle_power_kW", 15}, {"spindle_torque_Nm", 95}, {"max_feed_mm_min", 20000}};

    // Bad live sources are refused when the machine is stored, naming the key.
    json bad = machine;
    bad["name"] = "bad";
    bad["live_source"] = {{"adapter", "127.0.0.1:99999"}};
    require_error(post_machine(bad), 400, "bad_request", "live_source.adapter");
    bad["live_source"] = {{"agent", "ftp://agent"}, {"device", "VMC"}};
    require_error(post_machine(bad), 400, "bad_request", "live_source.agent");
    bad["live_source"] = {{"adapter", address}, {"port", 7878}};
    require_error(post_machine(bad), 400, "bad_request", "live_source.port");
    bad["live_source"] = {{"adapter", address}, {"sampling", "often"}};
    require_error(post_machine(bad), 400, "bad_request", "live_source.sampling");

    json plain = machine;
    plain["name"] = "no source";
    auto created = [](const httplib::Result& r) {
        REQUIRE(r);
        INFO(r->body);
        REQUIRE(r->status == 201);
        return json::parse(r->body)["id"].get<std::int64_t>();
    };
    const std::int64_t plain_id = created(post_machine(plain));
    json with = machine;
    with["name"] = "VMC-1";
    with["live_source"] = {{"adapter", address}, {"sampling", "polled"}};
    const std::int64_t machine_id = created(post_machine(with));

    json spec = slot_spec();
    spec["machine_id"] = plain_id;
    require_error(c.Post("/api/v1/live", json{{"spec", spec}}.dump(), "application/json"), 400, "bad_request",
                  "no live_source");
    spec["machine_id"] = machine_id;
    auto r = c.Post("/api/v1/live", json{{"spec", spec}, {"idle_timeout_s", 1}}.dump(), "application/json");
    REQUIRE(r);
    INFO(r->body);
    REQUIRE(r->status == 201);
    const json started = json::parse(r->body);
    CHECK(started["source"] == "shdr://" + address);
    const json run = wait_closed(c, started["id"], 60);
    REQUIRE(run["state"] == "done");
    CHECK(run["machine_id"] == machine_id);
    CHECK(run["inputs"]["live"]["sampling"] == "polled");   // the machine's sampling
    CHECK(run["summary"]["samples"].get<int>() > 0);
}
