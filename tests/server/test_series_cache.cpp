// Forces windows read decoded chunks from a bounded in-memory cache: answers are the same cold
// and warm, the bound holds, /metrics reports it, and a deleted run's reused id never sees the
// old run's data. Plus the number text the series answers are written with.
#include "harness.hpp"
#include "server/number_text.hpp"

#include <regex>

using namespace cutload::test;

namespace {

std::string text_of(float v) {
    char buf[cutload::server::kTimeChars];
    return std::string(buf, cutload::server::write_float(buf, v));
}

std::string time_text(double t) {
    char buf[cutload::server::kTimeChars];
    return std::string(buf, cutload::server::write_time(buf, t));
}

double metric(const std::string& text, const std::string& name) {
    std::smatch m;
    REQUIRE(std::regex_search(text, m, std::regex("\n" + name + " ([0-9.e+]+)\n")));
    return std::stod(m[1]);
}

}  // namespace

TEST_CASE("number text: 7 significant digits for values and microseconds for times, trailing zeros trimmed") {
    CHECK(text_of(0.0f) == "0");
    CHECK(text_of(-0.0f) == "0");
    CHECK(text_of(1.5f) == "1.5");
    CHECK(text_of(-1234.5678f) == "-1234.568");
    CHECK(text_of(0.1f) == "0.1");
    CHECK(text_of(0.00123456789f) == "0.001234568");
    CHECK(text_of(9.99999999f) == "10");
    CHECK(text_of(1200.0f) == "1200");
    CHECK(text_of(123456789.0f) == "123456792");   // the float nearest 123456789
    CHECK(std::stof(text_of(1.5e-5f)) == 1.5e-5f);  // tiny: shortest form with an exponent
    CHECK(std::stof(text_of(3e12f)) == 3e12f);
    CHECK(text_of(std::numeric_limits<float>::quiet_NaN()) == "null");
    CHECK(time_text(1.0000004) == "1");
    CHECK(time_text(2.5e-5) == "0.000025");
    CHECK(time_text(-0.5) == "-0.5");
    CHECK(time_text(12.3456789) == "12.345679");
    for (float v : {3.14159265f, -271.828f, 0.0123457f, 65432.1f, 999.9999f}) {
        INFO(v);
        CHECK(std::stof(text_of(v)) == Approx(v).epsilon(1e-6));
    }
}

TEST_CASE("series cache: warm answers equal cold ones, the bound holds and /metrics shows it") {
    // A cache far smaller than the run's chunks: most reads miss and evict, answers stay right.
    TestServer ts([](cutload::server::ServerOptions& o) { o.cache_bytes = 256u << 10; });
    auto c = ts.client(ts.read_key);
    auto w = ts.client(ts.write_key);
    const auto id = body(upload(w, slot_log_csv(1.5), slot_spec()))["id"].get<int>();
    REQUIRE(wait_finished(w, id)["state"] == "done");
    const std::string base = "/api/v1/runs/" + std::to_string(id) + "/forces?max_points=300";
    const char* windows[] = {"", "&from_s=0.4&to_s=0.45", "&from_s=0.2&to_s=1.3", "&channels=fx_N,f_N&from_s=1&to_s=1.2"};
    std::vector<std::string> cold;
    for (const char* q : windows) cold.push_back(c.Get((base + q).c_str())->body);
    for (int round = 0; round < 2; ++round)
        for (std::size_t i = 0; i < cold.size(); ++i) {
            INFO(windows[i]);
            REQUIRE(c.Get((base + windows[i]).c_str())->body == cold[i]);
        }
    const std::string text = ts.admin().Get("/metrics")->body;
    REQUIRE(metric(text, "cutload_series_cache_limit_bytes") == 256 << 10);
    REQUIRE(metric(text, "cutload_series_cache_bytes") <= 256 << 10);
    REQUIRE(metric(text, "cutload_series_cache_bytes") > 0);
    REQUIRE(metric(text, "cutload_series_cache_hits_total") > 0);
    REQUIRE(metric(text, "cutload_series_cache_evictions_total") > 0);

    // Offered gzip, the answer comes compressed once (the client inflates it to the same text).
    for (std::size_t i = 0; i < cold.size(); ++i) {
        auto gz = c.Get((base + windows[i]).c_str(), {{"Accept-Encoding", "gzip, deflate, br"}});
        REQUIRE(gz->get_header_value("Content-Encoding") == "gzip");
        REQUIRE(gz->body == cold[i]);
    }
    // Other large answers too.
    auto doc = c.Get("/api/v1/openapi.json", {{"Accept-Encoding", "gzip"}});
    REQUIRE(doc->get_header_value("Content-Encoding") == "gzip");
    REQUIRE(json::parse(doc->body) == json::parse(cutload::server::openapi_json()));
    auto refused = c.Get(base.c_str(), {{"Accept-Encoding", "gzip;q=0"}});
    REQUIRE_FALSE(refused->has_header("Content-Encoding"));
    REQUIRE(refused->body == cold[0]);

    // Only the asked channels are written; the window is the one asked.
    json j = json::parse(cold[3]);
    REQUIRE(j.contains("fx_N"));
    REQUIRE(j.contains("f_N"));
    REQUIRE_FALSE(j.contains("fy_N"));
    REQUIRE(j["t_s"].front().get<double>() >= 1.0);
    REQUIRE(j["t_s"].back().get<double>() <= 1.2);
}

TEST_CASE("series cache: a deleted run's id given to a new upload answers the new run's data") {
    TestServer ts;
    auto w = ts.client(ts.write_key);
    const auto first = body(upload(w, slot_log_csv(1.2), slot_spec()))["id"].get<int>();
    REQUIRE(wait_finished(w, first)["state"] == "done");
    const std::string forces = "/api/v1/runs/" + std::to_string(first) + "/forces?max_points=100";
    const double end_first = body(w.Get(forces.c_str()))["to_s"];
    REQUIRE(w.Delete(("/api/v1/runs/" + std::to_string(first)).c_str())->status == 204);

    const auto second = body(upload(w, slot_log_csv(0.6), slot_spec()))["id"].get<int>();
    // SQLite hands out the highest id again once its row is gone; a PostgreSQL identity never
    // does, so there the stale answer cannot arise, and the new run's own data is checked.
    if (on_postgres())
        REQUIRE(second > first);
    else
        REQUIRE(second == first);
    REQUIRE(wait_finished(w, second)["state"] == "done");
    const json again = body(w.Get(("/api/v1/runs/" + std::to_string(second) + "/forces?max_points=100").c_str()));
    REQUIRE(again["to_s"].get<double>() < end_first - 0.5);
    REQUIRE(again["t_end_s"].back().get<double>() <= again["to_s"].get<double>());
}
