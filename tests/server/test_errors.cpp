// Rejected requests: each gets a 4xx JSON error naming the problem and leaves nothing behind.
#include "harness.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <sqlite3.h>

using namespace cutload::test;

namespace {

// Nothing of a rejected upload may remain: no run row, no upload, no temporary file.
void require_nothing_left(TestServer& ts) {
    auto c = ts.admin();
    REQUIRE(body(c.Get("/api/v1/runs"))["items"].empty());
    REQUIRE(files_under(ts.data_dir() / "uploads") == 0);
    REQUIRE(files_under(ts.data_dir() / "tmp") == 0);
}

}  // namespace

TEST_CASE("errors: bad log or spec or multipart are 400 and leave nothing behind") {
    TestServer ts;
    auto c = ts.client(ts.write_key);

    SECTION("bad log names the uploaded file and the line") {
        std::string log = slot_log_csv(0.2);
        log.replace(log.find("\n0.004,") + 1, 5, "0.0x4");
        require_error(upload(c, log, slot_spec()), 400, "bad_log", "slot.csv");
    }
    SECTION("a log without the x column") {
        require_error(upload(c, "t,y,z\n0,1,2\n", slot_spec()), 400, "bad_log", "x");
    }
    SECTION("an empty log") { require_error(upload(c, "", slot_spec()), 400, "bad_log", "empty"); }
    SECTION("bad spec names the key") {
        json spec = slot_spec();
        spec["tool"]["flutes"] = 0;
        require_error(upload(c, slot_log_csv(0.2), spec), 400, "bad_spec", "tool.flutes");
    }
    SECTION("spec that is not JSON") {
        httplib::MultipartFormDataItems items{{"log", slot_log_csv(0.2), "slot.csv", "text/csv"},
                                              {"spec", "{\"tool\": ", "", ""}};
        require_error(c.Post("/api/v1/runs", items), 400, "bad_spec", "not valid JSON");
    }
    SECTION("missing parts and wrong content type") {
        httplib::MultipartFormDataItems only_log{{"log", slot_log_csv(0.2), "slot.csv", "text/csv"}};
        require_error(c.Post("/api/v1/runs", only_log), 400, "bad_request", "spec");
        require_error(c.Post("/api/v1/runs", "{}", "application/json"), 400, "bad_request", "multipart");
    }
    SECTION("bad format option") {
        require_error(upload(c, slot_log_csv(0.2), slot_spec(), {{"format", "xml", "", ""}}), 400, "bad_request", "format");
    }
    require_nothing_left(ts);
}

TEST_CASE("errors: authentication and roles") {
    TestServer ts;
    auto anon = ts.client("");
    require_error(anon.Get("/api/v1/runs"), 401, "unauthorized", "Bearer");
    auto wrong = ts.client("clk_" + std::string(48, '0'));
    require_error(wrong.Get("/api/v1/runs"), 401, "unauthorized", "unknown");
    auto malformed = ts.client("clk_0000");
    require_error(malformed.Get("/api/v1/runs"), 401, "unauthorized", "malformed");
    auto reader = ts.client(ts.read_key);
    REQUIRE(reader.Get("/api/v1/runs")->status == 200);
    require_error(upload(reader, slot_log_csv(0.2), slot_spec()), 403, "forbidden", "write");
    json m{{"name", "M"}, {"spindle_power_kW", 1}, {"spindle_torque_Nm", 1}, {"max_feed_mm_min", 1}};
    require_error(reader.Post("/api/v1/machines", m.dump(), "application/json"), 403, "forbidden", "write");
    auto writer = ts.client(ts.write_key);
    json th{{"name", "t"}, {"metric", "peak_force_N"}, {"limit", 1}};
    require_error(writer.Post("/api/v1/thresholds", th.dump(), "application/json"), 403, "forbidden", "admin");
    require_error(writer.Get("/api/v1/webhooks"), 403, "forbidden", "admin");
    // Health and the API description need no key.
    REQUIRE(anon.Get("/healthz")->status == 200);
    REQUIRE(anon.Get("/api/v1/openapi.json")->status == 200);
    require_error(anon.Get("/metrics"), 401, "unauthorized");
    require_nothing_left(ts);
}

TEST_CASE("errors: anonymous reads only when enabled and only reads") {
    TestServer ts([](cutload::server::ServerOptions& o) { o.anonymous_loopback_reads = true; });
    auto anon = ts.client("");
    REQUIRE(anon.Get("/api/v1/runs")->status == 200);
    REQUIRE(anon.Get("/metrics")->status == 200);
    require_error(upload(anon, slot_log_csv(0.2), slot_spec()), 401, "unauthorized");
}

TEST_CASE("errors: unknown ids and routes are 404 with a JSON body") {
    TestServer ts;
    auto c = ts.admin();
    require_error(c.Get("/api/v1/runs/42"), 404, "not_found", "run 42");
    require_error(c.Get("/api/v1/runs/42/blocks"), 404, "not_found", "run 42");
    require_error(c.Post("/api/v1/runs/42/cancel"), 404, "not_found", "run 42");
    require_error(c.Delete("/api/v1/runs/42"), 404, "not_found", "run 42");
    require_error(c.Get("/api/v1/tools/7"), 404, "not_found", "tool 7");
    require_error(c.Get("/api/v1/alerts/7"), 404, "not_found", "alert 7");
    require_error(c.Get("/api/v1/nothing"), 404, "not_found", "/api/v1/nothing");
    require_error(c.Get("/api/v1/runs/abc"), 404, "not_found");
}

TEST_CASE("errors: body and row and job limits answer 413 and 429") {
    TestServer ts([](cutload::server::ServerOptions& o) {
        o.max_body_bytes = 64 * 1024;
        o.max_log_rows = 400;
        o.max_pending_jobs = 1;
    });
    auto c = ts.client(ts.write_key);
    require_error(upload(c, slot_log_csv(8.0), slot_spec()), 413, "payload_too_large", "limit");
    require_error(upload(c, slot_log_csv(1.0), slot_spec()), 413, "too_many_rows", "400");
    require_nothing_left(ts);
    // One job pending fills the queue; the next is refused until it finishes. The first job is
    // made slow on purpose (0.1 deg steps on a fine grid: seconds of work) so the check is certain.
    json slow = slot_spec();
    slow["resolution"] = {{"angle_step_deg", 0.1}, {"axial_step_mm", 0.02}, {"grid_mm", 0.025}};   // 16e6 cells
    auto r = upload(c, slot_log_csv(0.6), slow);
    REQUIRE(r->status == 202);
    auto refused = upload(c, slot_log_csv(0.2), slot_spec());
    require_error(refused, 429, "too_many_jobs", "limit 1");
    REQUIRE(refused->get_header_value("Retry-After") == "30");
    auto cancelled = c.Post("/api/v1/runs/" + std::to_string(json::parse(r->body)["id"].get<int>()) + "/cancel", "", "application/json");
    REQUIRE(cancelled);
    REQUIRE(cancelled->status < 300);
}

TEST_CASE("errors: a run whose estimated work passes a limit is a 400 naming the cause, before anything is stored") {
    // The slot log: 1 s at 10000 rpm, 166.7 revolutions; at the spec's 2 deg a step that is
    // 30000 force rows, plus one per sample of the 1 ms model. Its stock: 1000 x 10 mm at
    // 0.1 mm, 1e6 cells.
    SECTION("force rows") {
        TestServer ts([](cutload::server::ServerOptions& o) { o.max_force_rows = 20000; });
        auto c = ts.client(ts.write_key);
        const auto r = upload(c, slot_log_csv(1.0), slot_spec());
        require_error(r, 400, "too_much_work", "force_rows: the log's 0.998 s turn the spindle 166.3 revolutions");
        const std::string m = body(r)["error"]["message"];
        CHECK(m.find("at resolution.angle_step_deg 2 that is 3.09e+04 force rows, above the limit of 2e+04 "
                     "(--max-force-rows)") != std::string::npos);
        require_nothing_left(ts);
    }
    SECTION("stock cells") {
        TestServer ts([](cutload::server::ServerOptions& o) { o.max_stock_cells = 500'000; });
        auto c = ts.client(ts.write_key);
        require_error(upload(c, slot_log_csv(1.0), slot_spec()), 400, "too_much_work",
                      "stock_cells: resolution.grid_mm gives the stock box 1e+06 dexel cells, above the limit of 5e+05");
        require_nothing_left(ts);
    }
    SECTION("memory") {
        // 1e6 cells at 144 B (the stock and its stored copy) alone are 137 MB.
        TestServer ts([](cutload::server::ServerOptions& o) { o.max_job_memory_mb = 100; });
        auto c = ts.client(ts.write_key);
        require_error(upload(c, slot_log_csv(1.0), slot_spec()), 400, "too_much_work",
                      "above the limit of 100 MB (--max-job-memory-mb)");
        require_nothing_left(ts);
    }
    SECTION("inside the limits the same upload is queued") {
        TestServer ts([](cutload::server::ServerOptions& o) { o.max_force_rows = 40000; });
        auto c = ts.client(ts.write_key);
        REQUIRE(upload(c, slot_log_csv(1.0), slot_spec())->status == 202);
    }
}

TEST_CASE("errors: static files are served without path traversal") {
    TempDir web;
    std::ofstream(web.path() / "index.html") << "<h1>cutload</h1>";
    TestServer ts([&web](cutload::server::ServerOptions& o) { o.web_dir = web.path().string(); });
    std::ofstream(ts.dir.path() / "secret.txt") << "TOP-SECRET-CONTENT";
    auto c = ts.client("");
    auto index = c.Get("/");
    REQUIRE(index->status == 200);
    REQUIRE(index->body.find("cutload") != std::string::npos);
    for (const char* p : {"/../secret.txt", "/%2e%2e/secret.txt", "/..%2fsecret.txt", "/a/../../secret.txt"}) {
        auto r = c.Get(p);
        REQUIRE(r);
        INFO(p);
        REQUIRE(r->status == 404);
        REQUIRE(r->body.find("TOP-SECRET-CONTENT") == std::string::npos);
    }
}

TEST_CASE("errors: a POST without Content-Length is told how to send an empty body") {
    TestServer ts;
    const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
    REQUIRE(fd >= 0);
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_port = htons(static_cast<std::uint16_t>(ts.srv->port()));
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    REQUIRE(::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0);
    const std::string request = "POST /api/v1/runs/1/optimizations HTTP/1.1\r\nHost: 127.0.0.1\r\nAuthorization: Bearer " +
                                ts.write_key + "\r\nConnection: close\r\n\r\n";
    REQUIRE(::send(fd, request.data(), request.size(), 0) == static_cast<ssize_t>(request.size()));
    std::string answer;
    char buf[4096];
    for (ssize_t n; (n = ::recv(fd, buf, sizeof buf, 0)) > 0;) answer.append(buf, static_cast<std::size_t>(n));
    ::close(fd);
    INFO(answer);
    REQUIRE(answer.rfind("HTTP/1.1 400", 0) == 0);
    REQUIRE(answer.find("\"code\":\"bad_request\"") != std::string::npos);
    REQUIRE(answer.find("send a body or Content-Length: 0") != std::string::npos);
}
