// Shared by the server tests: a temporary directory, an in-process server on a random loopback
// port with one key per role, small synthetic dry-run logs and upload / poll helpers.
#pragma once

#include "server/server.hpp"
#include "test_store.hpp"

#include <catch2/catch.hpp>
#include <httplib.h>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>

namespace cutload::test {

using nlohmann::json;
namespace fs = std::filesystem;

class TempDir {
public:
    TempDir() {
        std::string tmpl = (fs::temp_directory_path() / "cutload-server-XXXXXX").string();
        if (!::mkdtemp(tmpl.data())) throw std::runtime_error("mkdtemp failed");
        path_ = tmpl;
    }
    ~TempDir() {
        std::error_code ec;
        fs::remove_all(path_, ec);
    }
    const fs::path& path() const { return path_; }

private:
    fs::path path_;
};

// A straight slot along +X at `feed_mm_min`, 10000 rpm, logged every 2 ms: `air_s` in the air
// before the stock edge, then cutting. Two blocks (N10 then N20 at half time).
inline std::string slot_log_csv(double duration_s, double feed_mm_min = 1200, double depth_mm = 2) {
    std::ostringstream o;
    o << "t,x,y,z,feed,spindle,block\n";
    const double v_mm_s = feed_mm_min / 60.0;
    const int n = static_cast<int>(duration_s / 0.002);
    for (int i = 0; i < n; ++i) {
        const double t = i * 0.002;
        o << t << ',' << -6.0 + v_mm_s * t << ",5," << -depth_mm << ',' << feed_mm_min << ",10000,"
          << (t < duration_s / 2 ? "N10" : "N20") << '\n';
    }
    return o.str();
}

inline json tool_json() {
    return json::parse(R"({"shape": "flat", "diameter_mm": 8, "flutes": 2, "helix_deg": 30, "corner_radius_mm": 0,
        "flute_length_mm": 20, "stickout_mm": 30, "holder": {"diameter_mm": 32, "length_mm": 40}})");
}

inline json material_json() {
    return json::parse(R"({"name": "A7050", "Ktc_N_mm2": 800, "Krc_N_mm2": 300, "Kac_N_mm2": 100,
        "Kte_N_mm": 20, "Kre_N_mm": 20, "Kae_N_mm": 5})");
}

// Stock long enough for slot_log_csv runs of up to ~50 s at 1200 mm/min.
inline json slot_spec() {
    return {{"tool", tool_json()},
            {"material", material_json()},
            {"stock", {{"box_mm", {{"min", {0, 0, -10}}, {"max", {1000, 10, 0}}}}}}};
}

struct TestServer {
    explicit TestServer(std::function<void(server::ServerOptions&)> tweak = {}) {
        opt.port = 0;
        opt.db_path = store_location(dir.path(), "test.db");
        opt.data_dir = (dir.path() / "test.db.data").string();
        opt.workers = 1;
        opt.use_opencl = false;   // tiny jobs: the scalar path avoids OpenCL start-up per test
        opt.webhook_backoff_s = 0.05;
        opt.webhook_timeout_s = 2;
        opt.drain_s = 0;
        if (tweak) tweak(opt);
        admin_key = server::create_api_key(opt.db_path, server::Role::Admin, "test admin");
        write_key = server::create_api_key(opt.db_path, server::Role::Write, "test writer");
        read_key = server::create_api_key(opt.db_path, server::Role::Read, "test reader");
        srv = std::make_unique<server::Server>(opt);
        srv->start();
    }

    httplib::Client client(const std::string& key) const {
        httplib::Client c("127.0.0.1", srv->port());
        if (!key.empty()) c.set_bearer_token_auth(key.c_str());
        c.set_read_timeout(30, 0);
        return c;
    }
    httplib::Client admin() const { return client(admin_key); }

    fs::path data_dir() const { return fs::path(opt.data_dir); }

    TempDir dir;
    server::ServerOptions opt;
    std::string admin_key, write_key, read_key;
    std::unique_ptr<server::Server> srv;
};

inline httplib::Result upload(httplib::Client& c, const std::string& log, const json& spec,
                              httplib::MultipartFormDataItems extra = {}) {
    httplib::MultipartFormDataItems items{{"log", log, "slot.csv", "text/csv"},
                                          {"spec", spec.dump(), "", "application/json"}};
    items.insert(items.end(), extra.begin(), extra.end());
    return c.Post("/api/v1/runs", items);
}

inline json body(const httplib::Result& r) {
    REQUIRE(r);
    INFO(r->body);
    return json::parse(r->body);
}

// Polls until the run leaves queued/running; returns the run.
inline json wait_finished(httplib::Client& c, std::int64_t id, double timeout_s = 20) {
    const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    for (;;) {
        auto r = c.Get(("/api/v1/runs/" + std::to_string(id)).c_str());
        REQUIRE(r);
        REQUIRE(r->status == 200);
        json run = json::parse(r->body);
        const std::string state = run["state"];
        if (state != "queued" && state != "running") return run;
        if (std::chrono::steady_clock::now() > until) FAIL("run " << id << " still " << state);
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
}

// Polls the newest delivery of a webhook until it leaves 'pending' (or timeout_s passes).
inline json wait_delivery_settled(httplib::Client& admin, std::int64_t hook_id, double timeout_s = 10) {
    const std::string path = "/api/v1/webhooks/" + std::to_string(hook_id) + "/deliveries";
    const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    json d;
    do {
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
        auto r = admin.Get(path.c_str());
        REQUIRE(r);
        d = json::parse(r->body)["items"][0];
    } while (d["state"] == "pending" && std::chrono::steady_clock::now() < until);
    return d;
}

inline void require_error(const httplib::Result& r, int status, const std::string& code, const std::string& in_message = "") {
    REQUIRE(r);
    INFO(r->body);
    REQUIRE(r->status == status);
    json j = json::parse(r->body);
    REQUIRE(j["error"]["code"] == code);
    REQUIRE(j["error"]["message"].get<std::string>().size() > 0);
    if (!in_message.empty()) REQUIRE(j["error"]["message"].get<std::string>().find(in_message) != std::string::npos);
}

inline std::size_t files_under(const fs::path& p) {
    std::size_t n = 0;
    if (!fs::exists(p)) return 0;
    for (const auto& e : fs::recursive_directory_iterator(p))
        if (e.is_regular_file()) ++n;
    return n;
}

}  // namespace cutload::test
