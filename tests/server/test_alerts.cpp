// Thresholds evaluated when a run finishes -> alerts -> webhook POSTs with retries and a log.
#include "harness.hpp"

#include <openssl/evp.h>
#include <openssl/hmac.h>

#include <cstdio>
#include <mutex>

using namespace cutload::test;

namespace {

std::string hmac_hex(const std::string& key, const std::string& data) {
    unsigned char md[EVP_MAX_MD_SIZE];
    unsigned int n = 0;
    HMAC(EVP_sha256(), key.data(), static_cast<int>(key.size()), reinterpret_cast<const unsigned char*>(data.data()),
         data.size(), md, &n);
    std::string s;
    char buf[3];
    for (unsigned i = 0; i < n; ++i) {
        std::snprintf(buf, sizeof buf, "%02x", md[i]);
        s += buf;
    }
    return s;
}

// A webhook receiver on loopback that fails its first `failures` requests with 503.
struct Receiver {
    explicit Receiver(int failures) : failures_left(failures) {
        http.Post("/hook", [this](const httplib::Request& req, httplib::Response& res) {
            std::lock_guard lk(mu);
            if (failures_left > 0) {
                --failures_left;
                ++failed;
                res.status = 503;
                return;
            }
            bodies.push_back(req.body);
            signatures.push_back(req.get_header_value("X-Cutload-Signature"));
            res.status = 204;
        });
        port = http.bind_to_any_port("127.0.0.1");
        thread = std::thread([this] { http.listen_after_bind(); });
    }
    ~Receiver() {
        http.stop();
        thread.join();
    }
    std::size_t received() {
        std::lock_guard lk(mu);
        return bodies.size();
    }

    httplib::Server http;
    std::thread thread;
    int port = 0;
    std::mutex mu;
    int failures_left = 0, failed = 0;
    std::vector<std::string> bodies, signatures;
};

}  // namespace

TEST_CASE("alerts: threshold trips at run end and the webhook gets it after retries and the alert is acked") {
    TestServer ts;
    Receiver receiver(2);
    auto admin = ts.admin();
    json m{{"name", "VMC"}, {"spindle_power_kW", 1.0}, {"spindle_torque_Nm", 70}, {"max_feed_mm_min", 20000}};
    const int machine = body(admin.Post("/api/v1/machines", m.dump(), "application/json"))["id"];
    m["name"] = "other";
    const int other_machine = body(admin.Post("/api/v1/machines", m.dump(), "application/json"))["id"];

    json force{{"name", "force over 20 N"}, {"metric", "peak_force_N"}, {"limit", 20}, {"severity", "critical"}};
    REQUIRE(admin.Post("/api/v1/thresholds", force.dump(), "application/json")->status == 201);
    json power{{"name", "power over 10 %"}, {"scope", "machine"}, {"machine_id", machine}, {"metric", "power_pct"}, {"limit", 10}};
    REQUIRE(admin.Post("/api/v1/thresholds", power.dump(), "application/json")->status == 201);
    json elsewhere{{"name", "other machine"}, {"scope", "machine"}, {"machine_id", other_machine}, {"metric", "peak_force_N"}, {"limit", 1}};
    REQUIRE(admin.Post("/api/v1/thresholds", elsewhere.dump(), "application/json")->status == 201);
    json huge{{"name", "never"}, {"metric", "peak_force_N"}, {"limit", 1e9}};
    REQUIRE(admin.Post("/api/v1/thresholds", huge.dump(), "application/json")->status == 201);
    require_error(admin.Post("/api/v1/thresholds", json{{"name", "x"}, {"metric", "speed"}, {"limit", 1}}.dump(), "application/json"),
                  400, "bad_request", "metric");
    require_error(admin.Post("/api/v1/thresholds", json{{"name", "x"}, {"metric", "peak_force_N"}}.dump(), "application/json"),
                  400, "bad_request", "limit");

    const std::string url = "http://127.0.0.1:" + std::to_string(receiver.port) + "/hook";
    json hook = body(admin.Post("/api/v1/webhooks", json{{"url", url}, {"secret", "s3cret"}}.dump(), "application/json"));
    REQUIRE(hook["has_secret"] == true);
    require_error(admin.Post("/api/v1/webhooks", json{{"url", "ftp://x"}}.dump(), "application/json"), 400, "bad_request", "url");

    auto r = upload(admin, slot_log_csv(1.0), slot_spec(), {{"machine_id", std::to_string(machine), "", ""}});
    REQUIRE(r->status == 202);
    json run = wait_finished(admin, body(r)["id"]);
    REQUIRE(run["state"] == "done");
    REQUIRE(run["summary"]["alerts"] == 2);
    REQUIRE(run["flagged"].get<bool>());

    json alerts = body(admin.Get(("/api/v1/alerts?run_id=" + std::to_string(run["id"].get<int>())).c_str()));
    REQUIRE(alerts["items"].size() == 2);
    json critical = body(admin.Get("/api/v1/alerts?severity=critical"))["items"];
    REQUIRE(critical.size() == 1);
    REQUIRE(critical[0]["metric"] == "peak_force_N");
    REQUIRE(critical[0]["value"].get<double>() == Approx(run["summary"]["peak_force_N"].get<double>()));
    REQUIRE(critical[0]["blocks"].size() == 2);
    REQUIRE(critical[0]["message"].get<std::string>().find("peak_force_N") != std::string::npos);

    // Two 503s, then delivered: three attempts in the log.
    const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    while (receiver.received() < 2 && std::chrono::steady_clock::now() < until)
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
    REQUIRE(receiver.received() == 2);
    REQUIRE(receiver.failed == 2);
    for (std::size_t i = 0; i < 2; ++i) {
        json payload = json::parse(receiver.bodies[i]);
        REQUIRE(payload["event"] == "alert.raised");
        REQUIRE(payload["alert"]["run_id"] == run["id"]);
        REQUIRE(receiver.signatures[i] == "sha256=" + hmac_hex("s3cret", receiver.bodies[i]));
    }
    json deliveries;
    for (int i = 0; i < 100; ++i) {   // the log row commits just after the receiver answers
        deliveries = body(admin.Get(("/api/v1/webhooks/" + std::to_string(hook["id"].get<int>()) + "/deliveries").c_str()));
        if (deliveries["items"][0]["state"] == "delivered" && deliveries["items"][1]["state"] == "delivered") break;
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    int attempts = 0, failed_attempts = 0;
    for (const auto& d : deliveries["items"]) {
        REQUIRE(d["state"] == "delivered");
        attempts += d["attempts"].get<int>();
        for (const auto& a : d["log"])
            if (a["status"] == 503) ++failed_attempts;
    }
    REQUIRE(attempts == 4);
    REQUIRE(failed_attempts == 2);

    // Acknowledge: recorded once, by the key that did it.
    auto writer = ts.client(ts.write_key);
    const std::string ack_path = "/api/v1/alerts/" + std::to_string(critical[0]["id"].get<int>()) + "/ack";
    json acked = body(writer.Post(ack_path.c_str(), json{{"note", "checked the program"}}.dump(), "application/json"));
    REQUIRE_FALSE(acked["acked_at"].is_null());
    REQUIRE(acked["acked_by"] == ts.write_key.substr(0, 10));
    REQUIRE(acked["ack_note"] == "checked the program");
    REQUIRE(body(admin.Get("/api/v1/alerts?acked=false"))["items"].size() == 1);
    require_error(ts.client(ts.read_key).Post(ack_path.c_str(), "", "application/json"), 403, "forbidden");
}

TEST_CASE("alerts: a receiver that never answers 2xx gets max attempts and the delivery fails") {
    TestServer ts([](cutload::server::ServerOptions& o) { o.webhook_max_attempts = 3; });
    Receiver receiver(1000);
    auto admin = ts.admin();
    json flag{{"name", "any flag"}, {"metric", "flag"}, {"flag", "force_limit"}};
    REQUIRE(admin.Post("/api/v1/thresholds", flag.dump(), "application/json")->status == 201);
    const std::string url = "http://127.0.0.1:" + std::to_string(receiver.port) + "/hook";
    const int hook = body(admin.Post("/api/v1/webhooks", json{{"url", url}}.dump(), "application/json"))["id"];
    json spec = slot_spec();
    spec["limits"] = {{"force_N", 20}};
    auto r = upload(admin, slot_log_csv(0.8), spec);
    REQUIRE(wait_finished(admin, body(r)["id"])["summary"]["alerts"] == 1);
    const json d = wait_delivery_settled(admin, hook);
    REQUIRE(d["state"] == "failed");
    REQUIRE(d["attempts"] == 3);
    REQUIRE(d["log"].size() == 3);
    REQUIRE(d["log"][2]["error"] == "HTTP 503");
}
