// Webhook targets: link-local (cloud metadata), unspecified and multicast addresses are refused at
// registration and again before each delivery; loopback and private networks are allowed.
#include "harness.hpp"

#include "server/webhooks.hpp"


using namespace cutload::test;

TEST_CASE("webhooks: link-local, unspecified and multicast targets are 400, private and loopback ones accepted") {
    TestServer ts;
    auto admin = ts.admin();
    auto post = [&](const std::string& url) { return admin.Post("/api/v1/webhooks", json{{"url", url}}.dump(), "application/json"); };
    require_error(post("http://169.254.169.254/latest/meta-data"), 400, "bad_request", "169.254.169.254 is a link-local address");
    require_error(post("http://[fe80::1]:8080/hook"), 400, "bad_request", "link-local");
    require_error(post("http://[::ffff:169.254.1.2]/hook"), 400, "bad_request", "link-local");
    require_error(post("http://0.0.0.0:9000/hook"), 400, "bad_request", "unspecified");
    require_error(post("http://224.0.0.1/hook"), 400, "bad_request", "multicast");
    REQUIRE(body(admin.Get("/api/v1/webhooks"))["items"].empty());
    for (const char* ok : {"http://10.1.2.3/mes/alerts", "http://192.168.0.20:8080/hook", "http://127.0.0.1:9/x",
                           "https://[::1]/hook", "http://mes.shop.local/hook"}) {
        INFO(ok);
        REQUIRE(post(ok)->status == 201);
    }
    // An update is checked the same way.
    const int id = body(admin.Get("/api/v1/webhooks"))["items"][0]["id"];
    auto put = admin.Put(("/api/v1/webhooks/" + std::to_string(id)).c_str(), json{{"url", "http://169.254.1.1/"}}.dump(),
                         "application/json");
    require_error(put, 400, "bad_request", "link-local");
}

TEST_CASE("webhooks: a stored link-local target is refused at delivery without a connection") {
    // A row from before the check (or a name pointed there later): the delivery logs the refusal.
    TestServer ts([](cutload::server::ServerOptions& o) { o.webhook_max_attempts = 2; });
    auto admin = ts.admin();
    {
        Sql sql(ts.opt.db_path);
        sql.exec("INSERT INTO webhooks(url, enabled, created_at) VALUES "
                 "('http://169.254.169.254/latest', TRUE, '2026-01-01T00:00:00Z')");
    }
    json flag{{"name", "any flag"}, {"metric", "flag"}, {"flag", "force_limit"}};
    REQUIRE(admin.Post("/api/v1/thresholds", flag.dump(), "application/json")->status == 201);
    json spec = slot_spec();
    spec["limits"] = {{"force_N", 20}};
    REQUIRE(wait_finished(admin, body(upload(admin, slot_log_csv(0.8), spec))["id"])["summary"]["alerts"] == 1);
    const int hook = body(admin.Get("/api/v1/webhooks"))["items"][0]["id"];
    const json d = wait_delivery_settled(admin, hook);
    INFO(d.dump());
    REQUIRE(d["state"] == "failed");
    REQUIRE(d["log"].size() == 2);
    const std::string error = d["log"][0]["error"];
    REQUIRE(error.rfind("refused: 169.254.169.254 is a link-local address", 0) == 0);
    REQUIRE(d["log"][0]["duration_ms"].get<double>() < 100);   // no connection was attempted
}

TEST_CASE("webhooks: host names are checked by what they resolve to") {
    using cutload::server::refused_webhook_host;
    REQUIRE(refused_webhook_host("localhost", true).empty());
    REQUIRE(refused_webhook_host("10.0.0.1", false).empty());
    REQUIRE(refused_webhook_host("mes.example", false).empty());   // a name is resolved at delivery
    REQUIRE(refused_webhook_host("169.254.0.1", true).find("link-local") != std::string::npos);
    REQUIRE(refused_webhook_host("fe80::1", false).find("link-local") != std::string::npos);
}

TEST_CASE("webhooks: an IPv6 address carrying a refused IPv4 address is refused as that address") {
    TestServer ts;
    auto admin = ts.admin();
    auto post = [&](const std::string& url) { return admin.Post("/api/v1/webhooks", json{{"url", url}}.dump(), "application/json"); };
    for (const char* url : {"http://[::169.254.169.254]/",                 // v4-compatible
                            "http://[::a9fe:a9fe]/latest",                 // the same, in hex
                            "http://[64:ff9b::a9fe:a9fe]/",                // NAT64 (RFC 6052)
                            "http://[64:ff9b::169.254.169.254]:80/",
                            "http://[64:ff9b:1::a9fe:a9fe]/",              // local-use NAT64 (RFC 8215)
                            "http://[::ffff:0:169.254.169.254]/",          // SIIT translated
                            "http://[::FFFF:A9FE:0101]/",                  // v4-mapped, in hex and capitals
                            "http://[2002:a9fe:a9fe::1]/",                 // 6to4
                            "http://[fd00::5efe:169.254.169.254]/",        // ISATAP interface id
                            "http://[::224.0.0.1]/", "http://[64:ff9b::]/"}) {
        INFO(url);
        const auto r = post(url);
        REQUIRE(r);
        INFO(r->body);
        REQUIRE(r->status == 400);
        const std::string message = json::parse(r->body)["error"]["message"];
        REQUIRE(message.find("carries the IPv4 address") != std::string::npos);
    }
    // Embedded private and public addresses are as fine as the addresses themselves; ::1 stays loopback.
    for (const char* ok : {"http://[::ffff:10.0.0.5]/hook", "http://[64:ff9b::c0a8:14]/hook", "http://[2002:c0a8:0001::1]/hook",
                           "https://[::1]/hook", "http://[2001:db8::1]/hook"}) {
        INFO(ok);
        REQUIRE(post(ok)->status == 201);
    }
    using cutload::server::refused_webhook_host;
    REQUIRE(refused_webhook_host("64:ff9b::a9fe:a9fe", false).find("169.254.169.254") != std::string::npos);
    // Teredo: the client's address is stored inverted.
    REQUIRE(refused_webhook_host("2001:0:4136:e378:8000:63bf:5601:5601", false).find("169.254.169.254 is a link-local") !=
            std::string::npos);
}
