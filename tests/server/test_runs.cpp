// Libraries CRUD, upload -> job -> results, window queries with decimation, run listing.
#include "harness.hpp"

#include <algorithm>

using namespace cutload::test;

TEST_CASE("libraries: create read list replace delete with cursor and unique names") {
    TestServer ts;
    auto c = ts.admin();
    json m{{"name", "VMC-1"}, {"spindle_power_kW", 11}, {"spindle_torque_Nm", 70}, {"max_feed_mm_min", 20000}};
    auto r = c.Post("/api/v1/machines", m.dump(), "application/json");
    REQUIRE(r->status == 201);
    const auto id = body(r)["id"].get<std::int64_t>();
    require_error(c.Post("/api/v1/machines", m.dump(), "application/json"), 409, "name_taken", "VMC-1");

    m["name"] = "VMC-2";
    REQUIRE(c.Post("/api/v1/machines", m.dump(), "application/json")->status == 201);
    json page1 = body(c.Get("/api/v1/machines?limit=1"));
    REQUIRE(page1["items"].size() == 1);
    REQUIRE(page1["items"][0]["name"] == "VMC-1");
    json page2 = body(c.Get(("/api/v1/machines?limit=1&cursor=" + page1["next_cursor"].get<std::string>()).c_str()));
    REQUIRE(page2["items"][0]["name"] == "VMC-2");
    REQUIRE(page2["next_cursor"].is_null());

    m["name"] = "VMC-1b";
    m["spindle_power_kW"] = 15;
    json put = body(c.Put(("/api/v1/machines/" + std::to_string(id)).c_str(), m.dump(), "application/json"));
    REQUIRE(put["spindle_power_kW"] == 15);
    REQUIRE(body(c.Get(("/api/v1/machines/" + std::to_string(id)).c_str()))["name"] == "VMC-1b");

    json tool{{"name", "D8 flat"}, {"tool", tool_json()}, {"limits", {{"force_N", 500}}}};
    REQUIRE(c.Post("/api/v1/tools", tool.dump(), "application/json")->status == 201);
    tool["name"] = "broken";
    tool["tool"]["diameter_mm"] = -1;
    require_error(c.Post("/api/v1/tools", tool.dump(), "application/json"), 400, "bad_spec", "tool.diameter_mm");
    json mat = material_json();
    REQUIRE(c.Post("/api/v1/materials", mat.dump(), "application/json")->status == 201);
    mat["Ktc_N_mm2"] = "lots";
    mat["name"] = "other";
    require_error(c.Post("/api/v1/materials", mat.dump(), "application/json"), 400, "bad_spec", "Ktc_N_mm2");

    REQUIRE(c.Delete(("/api/v1/machines/" + std::to_string(id)).c_str())->status == 204);
    require_error(c.Get(("/api/v1/machines/" + std::to_string(id)).c_str()), 404, "not_found", "machine");
    require_error(c.Delete(("/api/v1/machines/" + std::to_string(id)).c_str()), 404, "not_found");
}

TEST_CASE("runs: upload and poll to done then blocks and forces windows with envelope decimation and CSV and motion") {
    TestServer ts([](cutload::server::ServerOptions& o) { o.max_points = 100000; });
    auto c = ts.client(ts.write_key);
    auto r = upload(c, slot_log_csv(1.5), slot_spec(), {{"program", "O1000", "", ""}, {"name", "slot", "", ""}});
    REQUIRE(r->status == 202);
    const json queued = body(r);
    REQUIRE(r->get_header_value("Location") == "/api/v1/runs/" + std::to_string(queued["id"].get<int>()));
    const auto id = std::to_string(queued["id"].get<int>());
    // The upload is on disk before 202 came back.
    REQUIRE(files_under(ts.data_dir() / "uploads" / id) == 1);

    json run = wait_finished(c, queued["id"]);
    REQUIRE(run["state"] == "done");
    REQUIRE(run["progress"] == 1.0);
    REQUIRE(run["program"] == "O1000");
    REQUIRE(run["summary"]["samples"].get<int>() > 1000);
    REQUIRE(run["summary"]["peak_force_N"].get<double>() > 10);

    json blocks = body(c.Get(("/api/v1/runs/" + id + "/blocks").c_str()));
    REQUIRE(blocks["items"].size() == 2);
    REQUIRE(blocks["items"][0]["block"] == "N10");
    REQUIRE(blocks["items"][1]["peak_force_N"].get<double>() > 10);

    // Whole run at full resolution, then decimated to 50 buckets: the envelope must contain
    // every raw value and reach the raw extremes exactly.
    const int samples = run["summary"]["samples"];
    json raw = body(c.Get(("/api/v1/runs/" + id + "/forces?max_points=100000").c_str()));
    REQUIRE_FALSE(raw["decimated"].get<bool>());
    REQUIRE(raw["count"] == samples);
    const auto& f = raw["f_N"];
    const double raw_max = *std::max_element(f.begin(), f.end());
    json dec = body(c.Get(("/api/v1/runs/" + id + "/forces?max_points=50").c_str()));
    REQUIRE(dec["decimated"].get<bool>());
    REQUIRE(dec["count"].get<int>() <= 50);
    REQUIRE(dec["count"].get<int>() >= 40);
    const auto& fmax = dec["f_N"]["max"];
    const auto& fmin = dec["f_N"]["min"];
    REQUIRE(*std::max_element(fmax.begin(), fmax.end()) == Approx(raw_max));
    for (std::size_t i = 0; i < fmax.size(); ++i) REQUIRE(fmin[i].get<double>() <= fmax[i].get<double>());
    for (std::size_t i = 0; i < raw["t_s"].size(); ++i) {
        const double t = raw["t_s"][i];
        auto b = std::upper_bound(dec["t_s"].begin(), dec["t_s"].end(), t, [](double v, const json& e) { return v < e.get<double>(); });
        REQUIRE(b != dec["t_s"].begin());
        const auto k = static_cast<std::size_t>(b - dec["t_s"].begin() - 1);
        REQUIRE(f[i].get<double>() <= fmax[k].get<double>() + 1e-3);
        REQUIRE(f[i].get<double>() >= fmin[k].get<double>() - 1e-3);
    }

    // A narrow window answers at full resolution with only rows inside it.
    json win = body(c.Get(("/api/v1/runs/" + id + "/forces?from_s=1.0&to_s=1.01&max_points=2000").c_str()));
    REQUIRE_FALSE(win["decimated"].get<bool>());
    REQUIRE(win["count"].get<int>() > 100);   // 2 degree steps at 10000 rpm: 300 rows in 10 ms
    for (const auto& t : win["t_s"]) REQUIRE((t.get<double>() >= 1.0 && t.get<double>() <= 1.01));
    REQUIRE(win["block_names"]["1"] == "N20");

    auto csv = c.Get(("/api/v1/runs/" + id + "/forces?from_s=1.0&to_s=1.01").c_str(), {{"Accept", "text/csv"}});
    REQUIRE(csv->status == 200);
    REQUIRE(csv->get_header_value("Content-Type") == "text/csv");
    REQUIRE(csv->body.rfind("t_s,spindle_angle_deg,block,fx_N,fy_N,fz_N,f_N,", 0) == 0);
    REQUIRE(std::count(csv->body.begin(), csv->body.end(), '\n') == win["count"].get<int>() + 1);
    REQUIRE(csv->body.find(",N20,") != std::string::npos);

    json motion = body(c.Get(("/api/v1/runs/" + id + "/motion?max_points=100").c_str()));
    REQUIRE(motion["decimated"].get<bool>());
    REQUIRE(motion["feed_mm_min"]["max"][50].get<double>() == Approx(1200).epsilon(0.02));
    REQUIRE(motion["x_mm"]["min"][0].get<double>() == Approx(-6).margin(0.1));

    require_error(c.Get(("/api/v1/runs/" + id + "/forces?max_points=1").c_str()), 400, "bad_request", "max_points");
    require_error(c.Get(("/api/v1/runs/" + id + "/forces?from_s=abc").c_str()), 400, "bad_request", "from_s");
    require_error(c.Get(("/api/v1/runs/" + id + "/forces?from_s=2&to_s=1").c_str()), 400, "bad_request", "before");
}

TEST_CASE("runs: library references fill the spec and limits and base_run starts from the final stock") {
    TestServer ts;
    auto c = ts.admin();
    json tool{{"name", "D8"}, {"tool", tool_json()}, {"limits", {{"force_N", 50}}}};
    const auto tool_id = body(c.Post("/api/v1/tools", tool.dump(), "application/json"))["id"].get<int>();
    const auto mat_id = body(c.Post("/api/v1/materials", material_json().dump(), "application/json"))["id"].get<int>();
    json m{{"name", "VMC"}, {"spindle_power_kW", 0.1}, {"spindle_torque_Nm", 70}, {"max_feed_mm_min", 20000}};
    const auto machine_id = body(c.Post("/api/v1/machines", m.dump(), "application/json"))["id"].get<int>();

    json spec{{"tool_id", tool_id}, {"material_id", mat_id}, {"stock", slot_spec()["stock"]}};
    auto r = upload(c, slot_log_csv(1.0), spec, {{"machine_id", std::to_string(machine_id), "", ""}});
    REQUIRE(r->status == 202);
    json run = wait_finished(c, body(r)["id"]);
    REQUIRE(run["state"] == "done");
    REQUIRE(run["machine_id"] == machine_id);
    REQUIRE(run["inputs"]["spec"]["limits"]["force_N"] == 50.0);     // from the tool
    REQUIRE(run["inputs"]["spec"]["limits"]["power_kW"] == 0.1);     // from the machine
    REQUIRE(run["summary"]["flags"]["force_limit"].get<int>() >= 1);
    REQUIRE(run["flagged"].get<bool>());
    json flagged = body(c.Get(("/api/v1/runs/" + std::to_string(run["id"].get<int>()) + "/blocks?flagged=true").c_str()));
    REQUIRE(flagged["items"].size() >= 1);

    // The same path again on the first run's stock cuts only air.
    auto r2 = upload(c, slot_log_csv(1.0), spec, {{"base_run", std::to_string(run["id"].get<int>()), "", ""}});
    REQUIRE(r2->status == 202);
    json run2 = wait_finished(c, body(r2)["id"]);
    REQUIRE(run2["state"] == "done");
    REQUIRE(run2["summary"]["removed_mm3"].get<double>() < 0.05 * run["summary"]["removed_mm3"].get<double>());

    require_error(upload(c, slot_log_csv(0.2), spec, {{"base_run", "999", "", ""}}), 404, "not_found", "base_run 999");
    json both = spec;
    both["tool"] = tool_json();
    require_error(upload(c, slot_log_csv(0.2), both), 400, "bad_spec", "tool_id");
    json missing = spec;
    missing["material_id"] = 12345;
    require_error(upload(c, slot_log_csv(0.2), missing), 404, "not_found", "material_id 12345");
}

TEST_CASE("runs: list filters and cursor pagination and cancel of a queued run and delete removes files") {
    TestServer ts([](cutload::server::ServerOptions& o) { o.workers = 1; });
    auto c = ts.admin();
    // The first (longer) job keeps the single worker busy so the others stay queued.
    std::vector<int> ids;
    for (int i = 0; i < 3; ++i) {
        auto r = upload(c, slot_log_csv(i == 0 ? 6.0 : 0.4), slot_spec(), {{"program", i == 2 ? "O2" : "O1", "", ""}});
        REQUIRE(r->status == 202);
        ids.push_back(body(r)["id"]);
    }
    json cancelled = body(c.Post(("/api/v1/runs/" + std::to_string(ids[2]) + "/cancel").c_str()));
    REQUIRE(cancelled["state"] == "cancelled");
    require_error(c.Post(("/api/v1/runs/" + std::to_string(ids[2]) + "/cancel").c_str()), 409, "conflict", "cancelled");
    for (int id : {ids[0], ids[1]}) REQUIRE(wait_finished(c, id)["state"] == "done");

    json page = body(c.Get("/api/v1/runs?limit=2"));
    REQUIRE(page["items"].size() == 2);
    REQUIRE(page["items"][0]["id"] == ids[2]);   // newest first
    json rest = body(c.Get(("/api/v1/runs?limit=2&cursor=" + page["next_cursor"].get<std::string>()).c_str()));
    REQUIRE(rest["items"].size() == 1);
    REQUIRE(rest["items"][0]["id"] == ids[0]);
    REQUIRE(body(c.Get("/api/v1/runs?program=O2"))["items"].size() == 1);
    REQUIRE(body(c.Get("/api/v1/runs?state=done"))["items"].size() == 2);
    REQUIRE(body(c.Get("/api/v1/runs?flagged=true"))["items"].empty());
    REQUIRE(body(c.Get("/api/v1/runs?created_since=2000-01-01T00:00:00Z"))["items"].size() == 3);
    REQUIRE(body(c.Get("/api/v1/runs?created_until=2000-01-01"))["items"].empty());
    require_error(c.Get("/api/v1/runs?state=sleeping"), 400, "bad_request", "state");
    require_error(c.Get("/api/v1/runs?created_since=yesterday"), 400, "bad_request", "created_since");
    require_error(c.Get(("/api/v1/runs/" + std::to_string(ids[2]) + "/forces").c_str()), 409, "not_done", "cancelled");

    REQUIRE(c.Delete(("/api/v1/runs/" + std::to_string(ids[0])).c_str())->status == 204);
    REQUIRE_FALSE(fs::exists(ts.data_dir() / "uploads" / std::to_string(ids[0])));
    require_error(c.Get(("/api/v1/runs/" + std::to_string(ids[0])).c_str()), 404, "not_found", "run");
    require_error(c.Get(("/api/v1/runs/" + std::to_string(ids[0]) + "/forces").c_str()), 404, "not_found");
}

TEST_CASE("runs: the bundled demo log and spec run to done through the API") {
    const fs::path log = fs::path(CUTLOAD_SOURCE_DIR) / "data" / "demo_dryrun.csv";
    const fs::path spec = fs::path(CUTLOAD_SOURCE_DIR) / "data" / "demo_run.json";
    REQUIRE(fs::exists(log));
    REQUIRE(fs::exists(spec));
    auto read = [](const fs::path& p) {
        std::ifstream in(p);
        std::stringstream ss;
        ss << in.rdbuf();
        return ss.str();
    };
    TestServer ts;
    auto c = ts.admin();
    auto r = upload(c, read(log), json::parse(read(spec)));
    REQUIRE(r->status == 202);
    json run = wait_finished(c, body(r)["id"], 120);
    INFO(run.dump());
    REQUIRE(run["state"] == "done");
    REQUIRE(run["summary"]["blocks"].get<int>() > 3);
    REQUIRE(run["summary"]["removed_mm3"].get<double>() > 0);
    const std::string id = std::to_string(run["id"].get<int>());
    json forces = body(c.Get(("/api/v1/runs/" + id + "/forces?max_points=500&channels=f_N,torque_Nm").c_str()));
    REQUIRE(forces["decimated"].get<bool>());
    REQUIRE(forces.contains("f_N"));
    REQUIRE_FALSE(forces.contains("fx_N"));
    REQUIRE(forces["f_N"]["max"].size() == forces["count"].get<std::size_t>());
    require_error(c.Get(("/api/v1/runs/" + id + "/forces?channels=speed").c_str()), 400, "bad_request", "speed");
}

TEST_CASE("runs: cancelling a running run stops it and stores no results") {
    TestServer ts;
    auto c = ts.client(ts.write_key);
    json slow = slot_spec();   // seconds of work, so the cancel lands while it computes
    slow["resolution"] = {{"angle_step_deg", 0.1}, {"axial_step_mm", 0.02}, {"grid_mm", 0.025}};   // 16e6 cells
    const std::int64_t id = body(upload(c, slot_log_csv(0.6), slow))["id"];
    const std::string url = "/api/v1/runs/" + std::to_string(id);
    const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(20);
    while (body(c.Get(url.c_str()))["state"] != "running") {
        REQUIRE(std::chrono::steady_clock::now() < until);
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    auto r = c.Post((url + "/cancel").c_str());
    REQUIRE(r);
    REQUIRE(r->status < 300);
    const json run = wait_finished(c, id, 20);
    REQUIRE(run["state"] == "cancelled");
    require_error(c.Get((url + "/forces").c_str()), 409, "not_done", "cancelled");
}
