// Issue 6 through the API: a dynamometer record attached to a finished run, compared, detached.
#include "harness.hpp"

#include <cmath>
#include <cstdio>

using namespace cutload::test;

namespace {

std::string dynoware_header(double rate_Hz) {
    char head[200];
    std::snprintf(head, sizeof head,
                  "DynoWare,Version 3.2.2.0\nMeasurement:,api test\nSampling rate [Hz]:,%.6f\nTime,Fx,Fy,Fz,Mz\ns,N,N,N,N*cm\n",
                  rate_Hz);
    return head;
}

// The run's own predicted forces as a DynoWare export seen by a dynamometer that carries the
// workpiece (force = minus the tool's) with its X and Y axes swapped relative to the machine.
std::string dyno_from_forces(const json& raw, double rate_Hz) {
    std::string out = dynoware_header(rate_Hz);
    const auto& t = raw["t_s"];
    const double t0_s = t[0];
    char line[160];
    for (std::size_t i = 0; i < t.size(); ++i) {
        std::snprintf(line, sizeof line, "%.9f,%.6g,%.6g,%.6g,0\n", t0_s + static_cast<double>(i) / rate_Hz,
                      -raw["fy_N"][i].get<double>(), -raw["fx_N"][i].get<double>(), -raw["fz_N"][i].get<double>());
        out += line;
    }
    return out;
}

}  // namespace

TEST_CASE("measurement: a run's own forces as a dynamometer record compare near zero error and bad files are 400 leaving nothing") {
    TestServer ts([](cutload::server::ServerOptions& o) { o.max_points = 200000; });
    auto c = ts.client(ts.write_key);
    auto up = upload(c, slot_log_csv(1.0), slot_spec());
    REQUIRE(up->status == 202);
    const auto id = std::to_string(body(up)["id"].get<int>());
    REQUIRE(wait_finished(c, std::stoll(id))["state"] == "done");
    const std::string route = "/api/v1/runs/" + id + "/measurement";
    const auto dir = ts.data_dir() / "uploads" / id;
    const std::size_t files_before = files_under(dir);

    require_error(c.Get(route.c_str()), 404, "not_found", "no measurement");

    json raw = body(c.Get(("/api/v1/runs/" + id + "/forces?max_points=200000").c_str()));
    REQUIRE_FALSE(raw["decimated"].get<bool>());
    const std::size_t n = raw["t_s"].size();
    const double rate_Hz = static_cast<double>(n - 1) / (raw["t_s"][n - 1].get<double>() - raw["t_s"][0].get<double>());
    const std::string dyno = dyno_from_forces(raw, rate_Hz);

    // Bad inputs: a clear 400 naming the problem, and nothing stored.
    require_error(c.Post(route.c_str(), httplib::MultipartFormDataItems{{"file", "Time,Fx,Fy\n0,1,2\n", "bad.csv", ""}}),
                  400, "bad_measurement", "bad.csv");
    require_error(c.Post(route.c_str(), httplib::MultipartFormDataItems{{"file", dyno, "dyno.csv", ""},
                                                                       {"axes", "0,1,0,1,0", "", ""}}),
                  400, "bad_measurement", "axes");
    require_error(c.Post(route.c_str(), httplib::MultipartFormDataItems{{"file", dyno, "dyno.csv", ""},
                                                                       {"from_s", "50", "", ""}}),
                  400, "bad_measurement");
    require_error(c.Post(route.c_str(), httplib::MultipartFormDataItems{{"log", dyno, "dyno.csv", ""}}), 400,
                  "bad_request", "file");
    REQUIRE(files_under(dir) == files_before);

    httplib::MultipartFormDataItems items{{"file", dyno, "dyno.csv", "text/csv"},
                                          {"axes", "0,1,0,1,0,0,0,0,1", "", ""},
                                          {"measured_on", "workpiece", "", ""}};
    auto r = c.Post(route.c_str(), items);
    REQUIRE(r->status == 201);
    REQUIRE(files_under(dir) == files_before + 2);   // stored before the answer
    const json attached = body(r)["report"];
    REQUIRE(attached["measured"]["file"] == "dyno.csv");
    REQUIRE(attached["measured"]["format"] == "dynoware");

    json got = body(c.Get((route + "?max_points=100").c_str()));
    const json& rep = got["report"];
    INFO(rep.dump());
    REQUIRE(std::abs(rep["offset_s"].get<double>()) <= 1.01 / rate_Hz);
    const json& overall = rep["overall"];
    const double peak_N = overall["resultant"]["peak_measured_N"];
    REQUIRE(peak_N > 10);
    for (const char* ax : {"x", "y", "z"}) {
        REQUIRE(overall[ax]["rmse_N"].get<double>() < 0.01 * peak_N);
        REQUIRE(std::abs(overall[ax]["peak_error_N"].get<double>()) < 0.01 * peak_N);
    }
    REQUIRE(overall["x"]["correlation"].get<double>() > 0.999);
    REQUIRE(rep["blocks"].size() == 2);

    // The measured series as recorded, mapped to tool / machine axes, decimated to a min / max envelope.
    const json& s = got["series"];
    REQUIRE(s["decimated"].get<bool>());
    REQUIRE(s["count"].get<int>() <= 100);
    REQUIRE(s["count"].get<int>() >= 90);
    double measured_fx_max = -1e9, predicted_fx_max = -1e9;
    for (const auto& v : s["fx_N"]["max"]) measured_fx_max = std::max(measured_fx_max, v.get<double>());
    for (const auto& v : raw["fx_N"]) predicted_fx_max = std::max(predicted_fx_max, v.get<double>());
    REQUIRE(measured_fx_max == Approx(predicted_fx_max).epsilon(0.001));
    for (std::size_t i = 0; i < s["t_s"].size(); ++i)
        REQUIRE(s["fz_N"]["min"][i].get<double>() <= s["fz_N"]["max"][i].get<double>());

    json narrow = body(c.Get((route + "?from_s=0.5&to_s=0.51&max_points=2000").c_str()));
    REQUIRE_FALSE(narrow["series"]["decimated"].get<bool>());
    for (const auto& t : narrow["series"]["t_s"]) REQUIRE((t.get<double>() >= 0.5 && t.get<double>() <= 0.51));

    // A reader cannot attach; a bad replacement keeps the attached record.
    auto reader = ts.client(ts.read_key);
    REQUIRE(reader.Post(route.c_str(), items)->status == 403);
    require_error(c.Post(route.c_str(), httplib::MultipartFormDataItems{{"file", "junk\n", "junk.csv", ""}}), 400,
                  "bad_measurement");
    REQUIRE(c.Get(route.c_str())->status == 200);

    // A zero offset given in the record's channels (Fx, Fy, Fz as recorded) is mapped like the forces,
    // -A z for a record of the workpiece, and removed instead of the one found in air: this record has
    // none, so the mean errors become A z, with A swapping X and Y.
    require_error(c.Post(route.c_str(), httplib::MultipartFormDataItems{{"file", dyno, "dyno.csv", ""},
                                                                       {"zero_N", "1,2", "", ""}}),
                  400, "bad_request", "zero_N");
    auto zeroed = items;
    zeroed.push_back({"zero_N", "1,2,3", "", ""});
    REQUIRE(c.Post(route.c_str(), zeroed)->status == 201);
    const json given = body(c.Get(route.c_str()))["report"];
    INFO(given.dump());
    REQUIRE(given["settings"]["zero_N"] == json::array({1, 2, 3}));
    REQUIRE(given["zero"]["source"] == "given");
    REQUIRE(given["zero"]["N"][0].get<double>() == Approx(-2));
    REQUIRE(given["zero"]["N"][1].get<double>() == Approx(-1));
    REQUIRE(given["zero"]["N"][2].get<double>() == Approx(-3));
    REQUIRE(given["overall"]["x"]["mean_error_N"].get<double>() == Approx(-2).margin(0.01));
    REQUIRE(given["overall"]["y"]["mean_error_N"].get<double>() == Approx(-1).margin(0.01));
    REQUIRE(given["overall"]["z"]["mean_error_N"].get<double>() == Approx(-3).margin(0.01));
    // Found in air instead, it is about nothing.
    REQUIRE(rep["zero"]["source"] != "given");
    for (int ax = 0; ax < 3; ++ax) REQUIRE(std::abs(rep["zero"]["N"][ax].get<double>()) < 0.01 * peak_N);

    REQUIRE(c.Delete(route.c_str())->status == 204);
    REQUIRE(files_under(dir) == files_before);
    require_error(c.Get(route.c_str()), 404, "not_found");
    require_error(c.Delete(route.c_str()), 404, "not_found");
}
