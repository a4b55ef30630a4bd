// What the web page's run view needs from the API: the final stock as a height field, alerts for
// blocks over the run's own limits without a threshold set up, the NC line and spindle speed of
// each compared block, and the feed optimizer's shop options.
#include "harness.hpp"

#include <cmath>

using namespace cutload::test;

namespace {

json get_json(httplib::Client& c, const std::string& path, int status = 200) {
    auto r = c.Get(path.c_str());
    REQUIRE(r);
    INFO(path << ": " << r->body);
    REQUIRE(r->status == status);
    return json::parse(r->body);
}

// Coarser than the default resolution: these runs check flags and alerts, not forces.
json spec_with_limits(const json& limits) {
    json s = slot_spec();
    s["limits"] = limits;
    s["resolution"] = {{"angle_step_deg", 4}, {"axial_step_mm", 0.5}, {"grid_mm", 0.5}};
    return s;
}

std::int64_t finished_run(httplib::Client& c, const json& spec, httplib::MultipartFormDataItems extra = {}) {
    auto r = upload(c, slot_log_csv(1.0), spec, std::move(extra));
    REQUIRE(r->status == 202);
    const std::int64_t id = body(r)["id"];
    REQUIRE(wait_finished(c, id, 30)["state"] == "done");
    return id;
}

json run_alerts(httplib::Client& c, std::int64_t run_id) {
    return get_json(c, "/api/v1/alerts?run_id=" + std::to_string(run_id))["items"];
}

// slot_log_csv(1.0) as a program (a straight slot from X-6 at F1200, N10 to half way, N20 on).
const char* kSlotProgram = "%\nO0007 (SLOT)\nN10 G90 G21 G17 G01 X4. Y5. Z-2. F1200 S10000 M03\nN20 X14.\nM30\n%\n";

json wait_optimization(httplib::Client& c, std::int64_t id) {
    const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(60);
    for (;;) {
        json o = get_json(c, "/api/v1/optimizations/" + std::to_string(id));
        if (o["state"] != "queued" && o["state"] != "running") return o;
        if (std::chrono::steady_clock::now() > until) FAIL("optimization " << id << " still " << o["state"]);
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
}

}  // namespace

TEST_CASE("view api: the final stock as a height field is the slot's closed form") {
    TestServer ts;
    auto c = ts.admin();
    // The slot: tool D8 along y = 5 at z = -2 from x = -6 to 14 mm; stock 1000 x 10 x 10 mm, top
    // at z 0, 0.1 mm rays. 40000 cells: 5 x 5 rays (0.5 mm) each, 2000 x 20 cells.
    const std::int64_t id = finished_run(c, slot_spec());
    const json f = get_json(c, "/api/v1/runs/" + std::to_string(id) + "/stock?max_cells=40000");
    REQUIRE(f["run_id"] == id);
    REQUIRE(f["rays_per_cell"] == 5);
    REQUIRE(f["nx"] == 2000);
    REQUIRE(f["ny"] == 20);
    REQUIRE(f["cell_mm"].get<double>() == Approx(0.5));
    REQUIRE(f["box_mm"]["max"][2] == 0);
    const json& top = f["top_mm"];
    REQUIRE(top.size() == 40000);
    const auto at = [&](double x, double y) {
        const int i = static_cast<int>(std::floor((x - f["x0_mm"].get<double>()) / 0.5));
        const int j = static_cast<int>(std::floor((y - f["y0_mm"].get<double>()) / 0.5));
        return top[static_cast<std::size_t>(j * 2000 + i)].get<double>();
    };
    // Cells whose every ray lies within 4 mm of y = 5 (y 1 .. 9) and behind the tool's end
    // (x < 14 - 4 = 10) are at the slot floor; cells beyond the tool's reach keep the stock top.
    for (double y : {1.25, 3.0, 5.0, 7.0, 8.75})
        for (double x : {0.25, 5.0, 9.75}) {
            INFO("x " << x << " y " << y);
            REQUIRE(at(x, y) == Approx(-2.0).margin(1e-3));
        }
    for (double y : {0.25, 9.75}) REQUIRE(at(5.0, y) == Approx(0.0));
    for (double x : {18.25, 100.0, 999.75}) REQUIRE(at(x, 5.0) == Approx(0.0));

    // Coarser: 1000000 / 400 rays per cell -> 50 x 50 rays, 200 x 2 cells, each the highest top.
    const json coarse = get_json(c, "/api/v1/runs/" + std::to_string(id) + "/stock?max_cells=400");
    REQUIRE(coarse["rays_per_cell"] == 50);
    REQUIRE(coarse["top_mm"].size() == 400);
    for (const auto& v : coarse["top_mm"]) REQUIRE(v.get<double>() == Approx(0.0));

    require_error(c.Get(("/api/v1/runs/" + std::to_string(id) + "/stock?max_cells=0").c_str()), 400, "bad_request",
                  "max_cells");
    require_error(c.Get("/api/v1/runs/999/stock"), 404, "not_found");
}

TEST_CASE("view api: blocks over the run's own limits raise an alert with no threshold set up") {
    SECTION("a force overrun is a warning naming the blocks") {
        TestServer ts;
        auto c = ts.admin();
        const std::int64_t id = finished_run(c, spec_with_limits({{"force_N", 20}}));
        const json alerts = run_alerts(c, id);
        REQUIRE(alerts.size() == 1);
        const json& a = alerts[0];
        REQUIRE(a["threshold_id"].is_null());
        REQUIRE(a["threshold_name"] == "run limits");
        REQUIRE(a["severity"] == "warning");
        REQUIRE(a["block_count"] == 2);
        REQUIRE(a["blocks"][0]["block"] == "N10");
        REQUIRE(a["message"].get<std::string>().find("over the run's own limits") != std::string::npos);
        const json run = get_json(c, "/api/v1/runs/" + std::to_string(id));
        REQUIRE(run["summary"]["alerts"] == 1);
        REQUIRE(run["flagged"] == true);
    }
    SECTION("a rapid in material is critical") {
        TestServer ts;
        auto c = ts.admin();
        // The slot's 1200 mm/min counts as a rapid when rapids start at 1000 mm/min.
        const std::int64_t id = finished_run(c, spec_with_limits({{"rapid_feed_mm_min", 1000}}));
        const json alerts = run_alerts(c, id);
        REQUIRE(alerts.size() == 1);
        REQUIRE(alerts[0]["severity"] == "critical");
        REQUIRE(alerts[0]["message"].get<std::string>().find("collision") != std::string::npos);
    }
    SECTION("a run within its limits raises none") {
        TestServer ts;
        auto c = ts.admin();
        REQUIRE(run_alerts(c, finished_run(c, spec_with_limits({{"force_N", 5000}}))).empty());
    }
    SECTION("an 'any flag' threshold that applies replaces it") {
        TestServer ts;
        auto c = ts.admin();
        json rule{{"name", "every flag"}, {"metric", "flag"}, {"flag", "any"}, {"severity", "critical"}};
        const std::int64_t rule_id = body(c.Post("/api/v1/thresholds", rule.dump(), "application/json"))["id"];
        const json alerts = run_alerts(c, finished_run(c, spec_with_limits({{"force_N", 20}})));
        REQUIRE(alerts.size() == 1);
        REQUIRE(alerts[0]["threshold_id"] == rule_id);
    }
    SECTION("a threshold for one flag leaves the other flags to it") {
        TestServer ts;
        auto c = ts.admin();
        // The slot trips both the force limit and, with rapids from 1000 mm/min, rapid in material.
        json rule{{"name", "force flag"}, {"metric", "flag"}, {"flag", "force_limit"}};
        const std::int64_t rule_id = body(c.Post("/api/v1/thresholds", rule.dump(), "application/json"))["id"];
        // A threshold scoped to another machine does not apply and covers nothing.
        json m{{"name", "elsewhere"}, {"spindle_power_kW", 10}, {"spindle_torque_Nm", 50}, {"max_feed_mm_min", 20000}};
        const std::int64_t machine = body(c.Post("/api/v1/machines", m.dump(), "application/json"))["id"];
        json other{{"name", "rapid elsewhere"}, {"scope", "machine"}, {"machine_id", machine}, {"metric", "flag"}, {"flag", "rapid_in_material"}};
        REQUIRE(c.Post("/api/v1/thresholds", other.dump(), "application/json")->status == 201);
        const json alerts = run_alerts(c, finished_run(c, spec_with_limits({{"force_N", 20}, {"rapid_feed_mm_min", 1000}})));
        REQUIRE(alerts.size() == 2);
        // Newest first: the run's own alert (raised after the thresholds) holds only the collision.
        REQUIRE(alerts[0]["threshold_id"].is_null());
        REQUIRE(alerts[0]["severity"] == "critical");
        REQUIRE(alerts[1]["threshold_id"] == rule_id);
    }
    SECTION("cutload serve --no-limit-alerts turns it off") {
        TestServer ts([](cutload::server::ServerOptions& o) { o.limit_alerts = false; });
        auto c = ts.admin();
        REQUIRE(run_alerts(c, finished_run(c, spec_with_limits({{"force_N", 20}}))).empty());
    }
}

TEST_CASE("view api: compared blocks carry their NC line and spindle speed, optimizer shop options") {
    TestServer ts;
    auto c = ts.admin();
    // A force limit just under the slot's peak: both blocks are flagged, and a lower feed clears them.
    const std::int64_t probe = finished_run(c, spec_with_limits(json::object()));
    const double peak_N = get_json(c, "/api/v1/runs/" + std::to_string(probe))["summary"]["peak_force_N"];
    const std::int64_t id = finished_run(c, spec_with_limits({{"force_N", 0.85 * peak_N}}),
                                         {{"nc_program", kSlotProgram, "slot.nc", "text/plain"}});
    const std::string base = "/api/v1/runs/" + std::to_string(id);
    const json program = get_json(c, base + "/program");
    const json& blocks = program["blocks"];
    REQUIRE(blocks.size() == 2);
    REQUIRE(blocks[0]["block"] == "N10");
    REQUIRE(blocks[0]["line"] == 3);   // "%", "O0007 (SLOT)", then N10
    REQUIRE(blocks[1]["line"] == 4);
    REQUIRE(blocks[0]["spindle_rpm"] == 10000);
    REQUIRE(blocks[1]["spindle_rpm"] == 10000);   // modal

    require_error(c.Post((base + "/optimizations").c_str(), R"({"never_raise": 1})", "application/json"), 400,
                  "bad_request", "never_raise");
    require_error(c.Post((base + "/optimizations").c_str(), R"({"feed_step_mm_min": -5})", "application/json"), 400,
                  "bad_request", "feed_step_mm_min");
    auto r = c.Post((base + "/optimizations").c_str(), R"({"target": 0.8, "only_flagged": true, "never_raise": true})",
                    "application/json");
    REQUIRE(r->status == 202);
    const json created = json::parse(r->body);
    REQUIRE(created["params"]["feed_step_mm_min"] == 50);   // the default step
    REQUIRE(created["params"]["only_flagged"] == true);
    const json o = wait_optimization(c, created["id"]);
    INFO(o.dump());
    REQUIRE(o["state"] == "done");
    REQUIRE(o["result"]["blocks"].size() == 2);
    for (const auto& b : o["result"]["blocks"]) {
        const double before = b["programmed_feed_mm_min"], after = b["recommended_feed_mm_min"];
        REQUIRE(after < before);
        REQUIRE(std::fmod(after, 50.0) == 0.0);
        REQUIRE(b["flags_before"] == json::array({"force_limit"}));
        REQUIRE(b["flags_after"] == json::array());
        REQUIRE(b["flags_cleared"] == json::array({"force_limit"}));
    }
}
