// Host and header hygiene, and JSON a client can send but a double cannot hold: anonymous
// loopback reads only for a loopback Host (no DNS rebinding), the bearer token taken exactly, and
// 1e400 anywhere in a JSON part or body a 400 naming the part, the byte and the key.
#include "harness.hpp"
#include "raw_http.hpp"

using namespace cutload::test;

namespace {

std::string get_runs(const std::string& host_line, const std::string& auth_line = "") {
    return "GET /api/v1/runs HTTP/1.1\r\n" + host_line + auth_line + "Connection: close\r\n\r\n";
}

json error_of(const std::string& answer) {
    INFO(answer);
    return json::parse(body_of(answer))["error"];
}

}  // namespace

TEST_CASE("hygiene: anonymous loopback reads answer only requests addressed to a loopback host") {
    TestServer ts([](cutload::server::ServerOptions& o) { o.anonymous_loopback_reads = true; });
    const int port = ts.srv->port();
    for (const std::string& host : std::vector<std::string>{"localhost", "localhost:8080", "LOCALHOST:1", "127.0.0.1", "127.0.0.1:" + std::to_string(port),
                                   "[::1]", "[::1]:8080"}) {
        INFO("Host: " << host);
        REQUIRE(status_of(raw_request(port, get_runs("Host: " + host + "\r\n"))) == 200);
    }
    // A page on another origin whose name was rebound to 127.0.0.1 says its own name.
    for (const std::string& host : std::vector<std::string>{"attacker.example", "attacker.example:8080", "localhost.attacker.example",
                                   "127.0.0.1.nip.io", "127.0.0.1:80@evil", "[::1]x", "[::2]:80", "localhost:", "localhost:99999x"}) {
        INFO("Host: " << host);
        const std::string answer = raw_request(port, get_runs("Host: " + host + "\r\n"));
        REQUIRE(status_of(answer) == 401);
        REQUIRE(error_of(answer)["code"] == "unauthorized");
    }
    // No Host, or two of them: a key is needed.
    REQUIRE(status_of(raw_request(port, "GET /api/v1/runs HTTP/1.0\r\n\r\n")) == 401);
    REQUIRE(status_of(raw_request(port, get_runs("Host: localhost\r\nHost: attacker.example\r\n"))) == 401);
    // With a key any Host is fine (a reverse proxy may rewrite it).
    REQUIRE(status_of(raw_request(port, get_runs("Host: attacker.example\r\n", "Authorization: Bearer " + ts.read_key + "\r\n"))) == 200);
}

TEST_CASE("hygiene: a bearer token is the key exactly: trailing bytes, NUL, whitespace are 401") {
    TestServer ts;
    const int port = ts.srv->port();
    const std::string& key = ts.read_key;
    auto with_auth = [&](const std::string& value) {
        return raw_request(port, get_runs("Host: 127.0.0.1\r\n", "Authorization: " + value + "\r\n"));
    };
    REQUIRE(status_of(with_auth("Bearer " + key)) == 200);
    REQUIRE(status_of(with_auth("bearer " + key)) == 200);   // the scheme is case-insensitive (RFC 7235)
    for (const std::string& bad : std::vector<std::string>{"Bearer " + key + "%00abc", "Bearer " + key + std::string("\0abc", 4), "Bearer " + key + " abc",
                                  "Bearer " + key + "\tabc", "Bearer " + key + "x", "Bearer  " + key, "Bearer " + key.substr(0, 40),
                                  "Bearer %20" + key, "Bearer " + key.substr(0, key.size() - 1) + "%00",
                                  "Bearer " + key + "%0d%0aX-Injected: 1", "Basic " + key, "Bearer", key}) {
        INFO("Authorization: " << cutload::test::json(bad).dump(-1, ' ', true, json::error_handler_t::replace));
        const std::string answer = with_auth(bad);
        REQUIRE(status_of(answer) == 401);
        REQUIRE(error_of(answer)["code"] == "unauthorized");
    }
    // Two Authorization headers, one good: refused rather than guessing which counts.
    REQUIRE(status_of(raw_request(port, get_runs("Host: 127.0.0.1\r\n", "Authorization: Bearer " + key + "\r\nAuthorization: Bearer x\r\n"))) ==
            401);
}

TEST_CASE("hygiene: 1e400 in a JSON part or body is a 400 naming the part, the byte and the key") {
    TestServer ts;
    auto c = ts.admin();

    SECTION("run spec") {
        std::string spec = slot_spec().dump();
        const std::string at = "\"diameter_mm\":8";
        spec.replace(spec.find(at), at.size(), "\"diameter_mm\":1e400");
        httplib::MultipartFormDataItems items{{"log", slot_log_csv(0.2), "slot.csv", "text/csv"}, {"spec", spec, "", ""}};
        auto r = c.Post("/api/v1/runs", items);
        require_error(r, 400, "bad_spec", "part spec: byte");
        require_error(r, 400, "bad_spec", "key tool.diameter_mm");
        require_error(r, 400, "bad_spec", "1e400");
    }
    SECTION("nc_options part") {
        httplib::MultipartFormDataItems items{{"log", slot_log_csv(0.2), "slot.csv", "text/csv"},
                                              {"spec", slot_spec().dump(), "", ""},
                                              {"nc_program", "N10 G1 X10 F1000\n", "p.nc", ""},
                                              {"nc_options", R"({"rapid_feed_mm_min": -1e400})", "", ""}};
        auto r = c.Post("/api/v1/runs", items);
        require_error(r, 400, "bad_request", "part nc_options: byte");
        require_error(r, 400, "bad_request", "key rapid_feed_mm_min");
    }
    SECTION("calibration test conditions, in an array") {
        httplib::MultipartFormDataItems items{{"tool", tool_json().dump(), "", ""},
                                              {"test", "t,fx,fy,fz\n0,1,2,3\n", "slot1.csv", ""},
                                              {"tests", R"({"slot1.csv": {"passes": [1, 2, 3e999]}})", "", ""}};
        require_error(c.Post("/api/v1/calibrations", items), 400, "bad_request", "key slot1.csv.passes[2]");
    }
    SECTION("a JSON body") {
        auto r = c.Post("/api/v1/thresholds", R"({"name": "x", "metric": "peak_force_N", "limit": 1e400})", "application/json");
        require_error(r, 400, "bad_json", "request body: byte");
        require_error(r, 400, "bad_json", "key limit");
    }
    SECTION("a syntax error still names the byte and the key") {
        auto r = c.Post("/api/v1/thresholds", R"({"name": "x", "limit": })", "application/json");
        require_error(r, 400, "bad_json", "request body is not valid JSON: byte");
        require_error(r, 400, "bad_json", "key limit");
    }
}

TEST_CASE("hygiene: bytes that are not UTF-8 in an error's text are escaped in a valid JSON body") {
    TestServer ts;
    auto c = ts.admin();
    // nlohmann's message quotes the bytes it read: 0x81 is no character in any encoding textio
    // reads, 0xE4 is a Latin-1 "ä".
    for (const std::string& bad : std::vector<std::string>{std::string("{\"name\": \"Fr\xE4sen\", \"limit\": }"), std::string("{\"name\": \"\x81\x81\"}")}) {
        auto r = c.Post("/api/v1/thresholds", bad, "application/json");
        REQUIRE(r);
        INFO(r->body);
        REQUIRE(r->status == 400);
        const json j = json::parse(r->body);   // would throw on invalid UTF-8
        const std::string message = j["error"]["message"];
        REQUIRE(message.find("\xEF\xBF\xBD") == std::string::npos);   // no U+FFFD: shown, not lost
    }
    auto r = c.Post("/api/v1/thresholds", std::string("{\"name\": \"\x81\x81\"}"), "application/json");
    REQUIRE(json::parse(r->body)["error"]["message"].get<std::string>().find("\\x81") != std::string::npos);
}
