// A run expecting more force rows than --max-raw-rows stores envelopes only (docs/api.md, "Long
// runs"). The same log run on a server that keeps every row is the reference: the summaries are
// equal, every raw row lies inside the envelope bucket the envelope-only run answers for its time,
// the extremes are the same, and narrow windows are answered (decimated) from the finest level kept.
#include "harness.hpp"

#include <algorithm>

using namespace cutload::test;

namespace {

json run_slot(TestServer& ts, const std::string& log) {
    auto c = ts.client(ts.write_key);
    json created = body(upload(c, log, slot_spec()));
    json run = wait_finished(c, created["id"].get<std::int64_t>(), 60);
    REQUIRE(run["state"] == "done");
    return run;
}

// Every raw value of `raw` (full resolution) lies within the bucket of `env` (decimated) holding its time.
void check_inside(const json& raw, const json& env, const std::string& channel) {
    const auto& t = raw["t_s"];
    const auto& v = raw[channel];
    const auto& lo = env[channel]["min"];
    const auto& hi = env[channel]["max"];
    std::size_t outside = 0;
    for (std::size_t i = 0; i < t.size(); ++i) {
        const double ti = t[i];
        auto b = std::upper_bound(env["t_s"].begin(), env["t_s"].end(), ti, [](double x, const json& e) { return x < e.get<double>(); });
        REQUIRE(b != env["t_s"].begin());
        const auto k = static_cast<std::size_t>(b - env["t_s"].begin() - 1);
        const double vi = v[i];
        outside += vi > hi[k].get<double>() + 1e-3 || vi < lo[k].get<double>() - 1e-3;
    }
    CHECK(outside == 0);
}

}  // namespace

TEST_CASE("long runs: past --max-raw-rows a run stores envelopes that hold every row of the full run") {
    const std::string log = slot_log_csv(2.2);   // about 60 000 force rows
    TestServer full;
    TestServer envelopes([](cutload::server::ServerOptions& o) { o.max_raw_rows = 5000; });
    const json a = run_slot(full, log);
    const json b = run_slot(envelopes, log);
    CHECK(a["summary"]["samples"] == b["summary"]["samples"]);
    CHECK(a["summary"]["peak_force_N"] == b["summary"]["peak_force_N"]);
    CHECK(a["summary"]["samples"].get<double>() > 50000);
    const std::string pa = "/api/v1/runs/" + std::to_string(a["id"].get<std::int64_t>());
    const std::string pb = "/api/v1/runs/" + std::to_string(b["id"].get<std::int64_t>());
    auto ca = full.client(full.read_key);
    auto cb = envelopes.client(envelopes.read_key);
    CHECK(body(ca.Get((pa + "/blocks").c_str()))["items"] == body(cb.Get((pb + "/blocks").c_str()))["items"]);

    // A narrow window: raw rows from the full run, envelopes (64 rows each) from the other.
    const std::string win = "/forces?from_s=1.0&to_s=1.02&max_points=2000";
    const json raw = body(ca.Get((pa + win).c_str()));
    const json env = body(cb.Get((pb + win).c_str()));
    REQUIRE_FALSE(raw["decimated"].get<bool>());
    REQUIRE(env["decimated"].get<bool>());
    CHECK(env["level"].get<int>() == 2);   // 60 000 rows / 8^2 <= 5000
    CHECK(env["count"].get<int>() >= raw["count"].get<int>() / 64 - 1);
    for (const char* ch : {"fx_N", "fy_N", "f_N"}) check_inside(raw, env, ch);

    // The whole run: the same extremes.
    const json wa = body(ca.Get((pa + "/forces?max_points=200").c_str()));
    const json wb = body(cb.Get((pb + "/forces?max_points=200").c_str()));
    const auto max_of = [](const json& w) {
        const auto& m = w["f_N"]["max"];
        return std::max_element(m.begin(), m.end())->get<double>();
    };
    CHECK(max_of(wb) == Approx(max_of(wa)));
    CHECK(wb["t_s"].front() == wa["t_s"].front());

    // The spool is gone once the run is done.
    for (const auto& e : fs::recursive_directory_iterator(envelopes.data_dir())) CHECK(e.path().extension() != ".spool");
}

TEST_CASE("long runs: resolution=full recomputes a window of an envelope-only run, the full run's very rows") {
    const std::string log = slot_log_csv(2.2);
    TestServer full;
    TestServer envelopes([](cutload::server::ServerOptions& o) { o.max_raw_rows = 5000; });
    const json a = run_slot(full, log);
    const json b = run_slot(envelopes, log);
    const std::string pa = "/api/v1/runs/" + std::to_string(a["id"].get<std::int64_t>());
    const std::string pb = "/api/v1/runs/" + std::to_string(b["id"].get<std::int64_t>());
    auto ca = full.client(full.read_key);
    auto cb = envelopes.client(envelopes.read_key);
    const auto same_channels = [](const json& x, const json& y) {
        for (const char* key : {"t_s", "block", "fx_N", "fy_N", "fz_N", "f_N", "torque_Nm", "chip_mm", "spindle_angle_deg"}) {
            INFO(key);
            CHECK(x[key] == y[key]);
        }
    };

    // Raw: the stored rows of the run that kept them, recomputed from the run that kept envelopes.
    for (const std::string win : {"/forces?from_s=1.0&to_s=1.02&max_points=2000", "/forces?from_s=2.0&to_s=2.05&max_points=5000"}) {
        INFO(win);
        const json raw = body(ca.Get((pa + win).c_str()));
        const json again = body(cb.Get((pb + win + "&resolution=full").c_str()));
        REQUIRE_FALSE(raw["decimated"].get<bool>());
        REQUIRE_FALSE(again["decimated"].get<bool>());
        CHECK(again["recomputed"] == true);
        CHECK(again["level"] == 0);
        CHECK(raw["count"].get<int>() > 500);
        CHECK(again["count"] == raw["count"]);
        same_channels(raw, again);
        CHECK(again["block_names"] == raw["block_names"]);
    }
    // Wider than max_points: min/max buckets made from every row (not from stored envelopes), so
    // each holds the full run's rows in it and its extremes are theirs.
    const json rows_full = body(ca.Get((pa + "/forces?from_s=0.5&to_s=1.0&max_points=20000").c_str()));
    REQUIRE_FALSE(rows_full["decimated"].get<bool>());
    const json env_again = body(cb.Get((pb + "/forces?from_s=0.5&to_s=1.0&max_points=300&resolution=full").c_str()));
    REQUIRE(env_again["decimated"].get<bool>());
    CHECK(env_again["count"].get<int>() == 300);
    for (const char* ch : {"fx_N", "fy_N", "f_N"}) {
        check_inside(rows_full, env_again, ch);
        const auto& v = rows_full[ch];
        const auto& m = env_again[ch]["max"];
        CHECK(std::max_element(m.begin(), m.end())->get<double>() == std::max_element(v.begin(), v.end())->get<double>());
    }
    CHECK(env_again["t_s"].front() == rows_full["t_s"].front());
    CHECK(env_again["t_end_s"].back() == rows_full["t_s"].back());
    // CSV too.
    const auto csv_full = ca.Get((pa + "/forces?from_s=1.0&to_s=1.01&format=csv").c_str());
    const auto csv_again = cb.Get((pb + "/forces?from_s=1.0&to_s=1.01&format=csv&resolution=full").c_str());
    REQUIRE(csv_again);
    CHECK(csv_again->status == 200);
    CHECK(csv_again->body == csv_full->body);

    // What it refuses, and why.
    const auto refused = [&](const std::string& query, int status, const std::string& words) {
        INFO(query);
        const auto res = cb.Get((pb + query).c_str());
        REQUIRE(res);
        CHECK(res->status == status);
        CHECK_THAT(res->body, Catch::Contains(words));
    };
    refused("/forces?resolution=full", 400, "needs a window");
    refused("/forces?resolution=full&from_s=0&to_s=11", 400, "at most 10 s");
    refused("/forces?resolution=full&from_s=1&to_s=0.5", 400, "must be after");
    refused("/forces?resolution=full&from_s=50&to_s=51", 400, "holds none of run");
    refused("/forces?resolution=full&from_s=1&to_s=2&source=commanded", 400, "actual forces");
    refused("/forces?resolution=fine&from_s=1&to_s=2", 400, "resolution");
}
