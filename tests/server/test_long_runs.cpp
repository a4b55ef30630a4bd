// A run expecting more force rows than --max-raw-rows stores envelopes only (docs/api.md, "Long
// runs"). The same log run on a server that keeps every row is the reference: the summaries are
// equal, every raw row lies inside the envelope bucket the envelope-only run answers for its time,
// the extremes are the same, and narrow windows are answered (decimated) from the finest level kept.
#include "harness.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <fstream>
#include <sstream>
#include <vector>

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

namespace {

// Three slot passes along X, each 1 mm deeper, with the tool lifted clear of the stock, brought
// back and plunged between them (the air moves are the run's clean points, where it keeps stock
// checkpoints), 2 ms samples.
std::string passes_with_lifts_csv() {
    std::ostringstream o;
    o << "t,x,y,z,feed,spindle,block\n";
    double t = 0;
    auto go = [&](double x0, double z0, double x1, double z1, double feed_mm_min, const std::string& block) {
        const double len = std::hypot(x1 - x0, z1 - z0), dur = len / (feed_mm_min / 60);
        const int n = std::max(1, static_cast<int>(dur / 0.002));
        for (int i = 0; i < n; ++i, t += 0.002) {
            const double u = static_cast<double>(i) / n;
            o << t << ',' << x0 + u * (x1 - x0) << ",5," << z0 + u * (z1 - z0) << ',' << feed_mm_min << ",10000," << block
              << '\n';
        }
    };
    for (int pass = 1; pass <= 3; ++pass) {
        const double z = -pass;
        go(-6, z, 24, z, 1200, "N" + std::to_string(pass) + "0");
        go(24, z, 24, 5, 3000, "N" + std::to_string(pass) + "1");
        go(24, 5, -6, 5, 3000, "N" + std::to_string(pass) + "2");
        go(-6, 5, -6, z - 1, 3000, "N" + std::to_string(pass) + "3");
    }
    return o.str();
}

std::vector<fs::path> checkpoint_files(const fs::path& data_dir) {
    std::vector<fs::path> files;
    for (const auto& e : fs::recursive_directory_iterator(data_dir))
        if (e.path().filename().string().ends_with(".stock.gz")) files.push_back(e.path());
    return files;
}

}  // namespace

TEST_CASE("long runs: a recomputed window resumes at the run's last stock checkpoint before it") {
    const std::string log = passes_with_lifts_csv();
    TestServer full([](cutload::server::ServerOptions& o) { o.checkpoint_every_s = 0; });
    TestServer envelopes([](cutload::server::ServerOptions& o) {
        o.max_raw_rows = 5000;
        o.checkpoint_every_s = 0.5;
    });
    const json a = run_slot(full, log);
    const json b = run_slot(envelopes, log);
    CHECK(checkpoint_files(full.data_dir()).empty());
    const auto files = checkpoint_files(envelopes.data_dir());
    REQUIRE(files.size() >= 2);
    const std::string pa = "/api/v1/runs/" + std::to_string(a["id"].get<std::int64_t>());
    const std::string pb = "/api/v1/runs/" + std::to_string(b["id"].get<std::int64_t>());
    auto ca = full.client(full.read_key);
    auto cb = envelopes.client(envelopes.read_key);
    // Windows in the second and third passes, and one across the second lift.
    const double pass_s = 30.0 / 20, lift_s = (6.0 + 30 + 7) / 50;
    const double second = pass_s + lift_s + 0.1, third = 2 * (pass_s + lift_s) + 0.2;
    auto window = [](double from_s, double to_s) {
        std::ostringstream q;
        q.precision(17);
        q << "/forces?from_s=" << from_s << "&to_s=" << to_s << "&max_points=20000";
        return q.str();
    };
    auto same_as_full = [&](double from_s, double to_s) {
        INFO(from_s << " .. " << to_s << " s");
        const json raw = body(ca.Get((pa + window(from_s, to_s)).c_str()));
        const json again = body(cb.Get((pb + window(from_s, to_s) + "&resolution=full").c_str()));
        REQUIRE_FALSE(raw["decimated"].get<bool>());
        CHECK(again["recomputed"] == true);
        CHECK(again["count"] == raw["count"]);
        for (const char* key : {"t_s", "block", "fx_N", "fy_N", "fz_N", "torque_Nm", "chip_mm"}) {
            INFO(key);
            CHECK(again[key] == raw[key]);
        }
        double peak_N = 0;
        for (const auto& f : raw["f_N"]) peak_N = std::max(peak_N, f.get<double>());
        return std::make_pair(again["walked_from_s"].get<double>(), peak_N);
    };
    for (const auto& [from_s, to_s] : {std::pair{second, second + 0.5}, std::pair{third, third + 0.3},
                                       std::pair{pass_s + lift_s - 0.4, pass_s + lift_s + 0.3}}) {
        const auto [walked_from_s, peak_N] = same_as_full(from_s, to_s);
        CHECK(walked_from_s > 0.5);
        CHECK(walked_from_s <= from_s);
        CHECK(peak_N > 50);
    }
    // Before the first checkpoint the walk starts with the log.
    CHECK(same_as_full(0.5, 0.8).first == 0);

    // A checkpoint that does not fit the motion (its sample is not at its time) only costs the walk
    // from the start: the rows are the same.
    {
        // The one the third pass's window resumes at: the latest at or before its start
        // (at-<sample>-<time's bits in hex>.stock.gz).
        auto sample_of = [](const fs::path& f) {
            const std::string name = f.filename().string();
            return std::stoull(name.substr(3, name.find('-', 3) - 3));
        };
        auto time_of = [](const fs::path& f) {
            const std::string name = f.filename().string();
            return std::bit_cast<double>(static_cast<std::uint64_t>(std::stoull(name.substr(name.find('-', 3) + 1, 16), nullptr, 16)));
        };
        fs::path latest;
        for (const auto& f : files)
            if (time_of(f) <= third && (latest.empty() || time_of(f) > time_of(latest))) latest = f;
        REQUIRE_FALSE(latest.empty());
        const std::string name = latest.filename().string();
        fs::rename(latest, latest.parent_path() / ("at-" + std::to_string(sample_of(latest) + 7) + name.substr(name.find('-', 3))));
        const auto [walked_from_s, peak_N] = same_as_full(third, third + 0.3);
        CHECK(walked_from_s == 0);
        CHECK(peak_N > 50);
    }
    // One that cannot be read neither.
    for (const auto& f : checkpoint_files(envelopes.data_dir())) {
        std::ofstream(f, std::ios::binary | std::ios::trunc) << "not a gzip stream";
    }
    CHECK(same_as_full(third, third + 0.3).first == 0);

    // The checkpoints go with their run.
    auto admin = envelopes.client(envelopes.admin_key);
    const auto del = admin.Delete(pb.c_str());
    REQUIRE(del);
    CHECK(del->status == 204);
    CHECK(checkpoint_files(envelopes.data_dir()).empty());
}

TEST_CASE("long runs: resolution=full of a log of two sessions is 409 not_recomputable, and it keeps no checkpoints") {
    // The control restarted: a silence of over 60 s starts a second session (docs/ingest.md).
    std::ostringstream log;
    log << "t,x,y,z,feed,spindle,block\n";
    for (const double t0 : {0.0, 100.0})
        for (int i = 0; i < 500; ++i) {
            const double t = i * 0.002;
            log << t0 + t << ',' << -6.0 + 20 * t + (t0 > 0 ? 20 : 0) << ",5,-2,1200,10000," << (t0 > 0 ? "N20" : "N10")
                << '\n';
        }
    TestServer ts([](cutload::server::ServerOptions& o) { o.checkpoint_every_s = 0.1; });
    const json run = run_slot(ts, log.str());
    CHECK(run["summary"]["samples"].get<double>() > 1000);
    auto c = ts.client(ts.read_key);
    const std::string p = "/api/v1/runs/" + std::to_string(run["id"].get<std::int64_t>());
    const auto res = c.Get((p + "/forces?from_s=100.2&to_s=100.4&resolution=full").c_str());
    require_error(res, 409, "not_recomputable", "2 sessions");
    CHECK(checkpoint_files(ts.data_dir()).empty());
}

TEST_CASE("long runs: a run cancelled after it kept stock checkpoints leaves none behind") {
    TestServer ts([](cutload::server::ServerOptions& o) { o.checkpoint_every_s = 0.5; });
    auto c = ts.admin();
    json spec = slot_spec();
    spec["resolution"] = {{"angle_step_deg", 0.1}, {"axial_step_mm", 0.1}, {"grid_mm", 0.1}};   // slow enough to catch
    const std::int64_t id = body(upload(c, passes_with_lifts_csv(), spec))["id"];
    const auto t0 = std::chrono::steady_clock::now();
    while (checkpoint_files(ts.data_dir()).empty() && std::chrono::steady_clock::now() - t0 < std::chrono::seconds(60))
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
    REQUIRE_FALSE(checkpoint_files(ts.data_dir()).empty());
    REQUIRE(c.Post(("/api/v1/runs/" + std::to_string(id) + "/cancel").c_str())->status == 202);
    const json run = wait_finished(c, id, 60);
    REQUIRE(run["state"] == "cancelled");
    CHECK(checkpoint_files(ts.data_dir()).empty());
}

TEST_CASE("long runs: one window is recomputed at a time, a second one meanwhile is 503 busy with Retry-After") {
    TestServer ts([](cutload::server::ServerOptions& o) {
        o.max_raw_rows = 5000;
        o.checkpoint_every_s = 0;
    });
    const json run = run_slot(ts, slot_log_csv(30.0));
    const std::string p = "/api/v1/runs/" + std::to_string(run["id"].get<std::int64_t>());
    // The first walks 29 s of motion before its window: seconds on the scalar path.
    int first_status = 0;
    std::thread t([&] {
        auto c = ts.client(ts.read_key);
        c.set_read_timeout(120, 0);
        const auto r = c.Get((p + "/forces?from_s=29&to_s=29.2&resolution=full").c_str());
        first_status = r ? r->status : -1;
    });
    auto c = ts.client(ts.read_key);
    int second_status = 0;
    std::string retry_after, second_body;
    const auto t0 = std::chrono::steady_clock::now();
    // Asked until it is refused (the first has taken the lock) or 5 s have passed.
    do {
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
        const auto r = c.Get((p + "/forces?from_s=1&to_s=1.2&resolution=full").c_str());
        REQUIRE(r);
        second_status = r->status;
        retry_after = r->get_header_value("Retry-After");
        second_body = r->body;
    } while (second_status == 200 && std::chrono::steady_clock::now() - t0 < std::chrono::seconds(5));
    t.join();
    CHECK(first_status == 200);
    CHECK(second_status == 503);
    CHECK_THAT(second_body, Catch::Contains("\"busy\"") && Catch::Contains("another window"));
    CHECK(retry_after == "1");
}
