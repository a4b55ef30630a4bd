// Issue 6 through the API: cutting coefficients identified from uploaded dynamometer tests.
#include "calib/dyno_fixture.hpp"
#include "force_model/calibrate.hpp"
#include "harness.hpp"

#include <fmt/format.h>

using namespace cutload::test;
namespace calib = cutload::calibtest;
namespace fm = cutload::force_model;

namespace {

constexpr double kRpm = 10000;
constexpr double kAxialMm = 2;
constexpr double kFeedsPerTooth[] = {0.04, 0.09, 0.14};
constexpr const char* kSeedAxes = "0,-1,0,-1,0,0,0,0,1";

// Slot tests at three feeds predicted with the fixture's true coefficients, recorded as a table
// dynamometer under the workpiece in the seed's axes would (runout, noise, zero offset, delay).
struct SlotTests {
    std::vector<std::string> files;
    json conditions = json::object();
};

const SlotTests& slot_tests() {
    static const SlotTests tests = [] {
        SlotTests t;
        TempDir dir;
        calib::DynoOptions dyno;
        // A longer idle lead-in than the fixture's default: the zero offset estimated from it is the
        // largest error in the small axial means, which alone set Kac and Kae in slot tests.
        dyno.delay_s = 0.6;
        for (std::size_t i = 0; i < std::size(kFeedsPerTooth); ++i) {
            const auto cut = calib::straight_cut(kFeedsPerTooth[i], kAxialMm, calib::Side::Slot, 0, kRpm);
            fm::PredictOptions o;
            o.device = fm::Device::Cpu;
            const std::string path = (dir.path() / "dyno.csv").string();
            dyno.seed = 200 + static_cast<unsigned>(i);
            calib::write_dyno_file(fm::predict(cut.motion, cut.spec, o), path, dyno);
            std::ifstream in(path);
            t.files.emplace_back(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
            const double feed_mm_min = kFeedsPerTooth[i] * calib::test_tool().flutes * kRpm;
            t.conditions[fmt::format("slot{}.csv", i)] = {
                {"spindle_rpm", kRpm}, {"feed_mm_min", feed_mm_min}, {"axial_mm", kAxialMm}, {"mode", "slot"}};
        }
        return t;
    }();
    return tests;
}

httplib::MultipartFormDataItems calibration_parts(const json& conditions, httplib::MultipartFormDataItems extra) {
    const SlotTests& t = slot_tests();
    httplib::MultipartFormDataItems items{{"tests", conditions.dump(), "", "application/json"}};
    if (std::none_of(extra.begin(), extra.end(), [](const auto& p) { return p.name == "axes"; }))
        items.push_back({"axes", kSeedAxes, "", ""});
    for (std::size_t i = 0; i < t.files.size(); ++i)
        items.push_back({"test", t.files[i], fmt::format("slot{}.csv", i), "text/csv"});
    items.insert(items.end(), extra.begin(), extra.end());
    return items;
}

void check_true_coefficients(const json& material) {
    const auto want = fm::coefficients_of(calib::true_material());
    for (std::size_t k = 0; k < 6; ++k) {
        const double got = material.at(fm::kCoefficientKeys[k]).get<double>();
        INFO(fm::kCoefficientKeys[k] << ": identified " << got << ", true " << want[k]);
        CHECK(std::abs(got / want[k] - 1) < 0.02);
    }
}

std::size_t material_count(httplib::Client& c) { return body(c.Get("/api/v1/materials"))["items"].size(); }

}  // namespace

TEST_CASE("calibration: slot tests at three feeds re-identify the coefficients within 2 % and save_as stores them") {
    TestServer ts;
    auto c = ts.client(ts.write_key);
    const json& conditions = slot_tests().conditions;

    auto r = c.Post("/api/v1/calibrations", calibration_parts(conditions, {{"tool", tool_json().dump(), "", ""},
                                                                           {"save_as", "A7050 calibrated", "", ""}}));
    REQUIRE(r->status == 201);
    const json got = body(r);
    INFO(got.dump());
    check_true_coefficients(got["material"]);
    REQUIRE(got["material"]["name"] == "A7050 calibrated");
    REQUIRE(got["fit"]["equations"] == 9);
    CHECK(got["fit"]["relative_rms_residual"].get<double>() < 0.01);
    CHECK(got["fit"]["condition_number"].get<double>() > 1);
    REQUIRE(got["tests"].size() == 3);
    for (const auto& t : got["tests"]) {
        CHECK(t["revolutions"].get<int>() >= 10);
        CHECK(t["zero_removed"].get<bool>());
        CHECK(t["residual_rms_N"].get<double>() < 0.02 * std::abs(t["mean_force_feed_frame_N"][1].get<double>()));
    }
    // Feed-normal mean force grows with the feed.
    CHECK(std::abs(got["tests"][2]["mean_force_feed_frame_N"][1].get<double>()) >
          std::abs(got["tests"][0]["mean_force_feed_frame_N"][1].get<double>()));

    const std::string location = r->get_header_value("Location");
    REQUIRE(location == fmt::format("/api/v1/materials/{}", got["saved"]["id"].get<int>()));
    const json stored = body(c.Get(location.c_str()));
    REQUIRE(stored["name"] == "A7050 calibrated");
    for (const char* k : fm::kCoefficientKeys) REQUIRE(stored[k].get<double>() == Approx(got["material"][k].get<double>()));

    // The same tests again under the same name: 409, nothing more stored.
    require_error(c.Post("/api/v1/calibrations", calibration_parts(conditions, {{"tool", tool_json().dump(), "", ""},
                                                                                {"save_as", "A7050 calibrated", "", ""}})),
                  409, "name_taken", "A7050 calibrated");
    REQUIRE(material_count(c) == 1);

    // A library tool by id, without save_as: 200, the same fit, nothing stored.
    auto tool = c.Post("/api/v1/tools", json{{"name", "flat 8"}, {"tool", tool_json()}}.dump(), "application/json");
    REQUIRE(tool->status == 201);
    const std::string tool_id = std::to_string(body(tool)["id"].get<int>());
    auto by_id = c.Post("/api/v1/calibrations", calibration_parts(conditions, {{"tool_id", tool_id, "", ""}}));
    REQUIRE(by_id->status == 200);
    const json again = body(by_id);
    REQUIRE(again["saved"].is_null());
    for (const char* k : fm::kCoefficientKeys) REQUIRE(again["material"][k].get<double>() == Approx(got["material"][k].get<double>()));
    REQUIRE(material_count(c) == 1);

    auto reader = ts.client(ts.read_key);
    REQUIRE(reader.Post("/api/v1/calibrations", calibration_parts(conditions, {{"tool", tool_json().dump(), "", ""}}))->status ==
            403);
}

TEST_CASE("calibration: bad tests are 400 naming the problem and store nothing") {
    TestServer ts;
    auto c = ts.client(ts.write_key);
    const json good = slot_tests().conditions;
    const httplib::MultipartFormDataItems tool{{"tool", tool_json().dump(), "", ""}, {"save_as", "never", "", ""}};
    auto post = [&](const json& conditions, httplib::MultipartFormDataItems extra = {}) {
        extra.insert(extra.end(), tool.begin(), tool.end());
        return c.Post("/api/v1/calibrations", calibration_parts(conditions, extra));
    };

    json missing = good;
    missing.erase("slot1.csv");
    require_error(post(missing), 400, "bad_request", "no conditions for test file 'slot1.csv'");

    json bad_mode = good;
    bad_mode["slot0.csv"]["mode"] = "climb";
    require_error(post(bad_mode), 400, "bad_request", "slot0.csv");

    json no_radial = good;
    no_radial["slot2.csv"]["mode"] = "down";
    require_error(post(no_radial), 400, "bad_request", "radial_mm is missing");

    json no_feed = good;
    no_feed["slot0.csv"].erase("feed_mm_min");
    require_error(post(no_feed), 400, "bad_request", "feed_mm_min");

    json extra_entry = good;
    extra_entry["slot9.csv"] = good["slot0.csv"];
    require_error(post(extra_entry), 400, "bad_request", "slot9.csv");

    json bad_test = good;
    bad_test["junk.csv"] = good["slot0.csv"];
    require_error(post(bad_test, {{"test", "Time,Fx,Fy\n0,1,2\n", "junk.csv", "text/csv"}}), 400, "bad_measurement",
                  "junk.csv");

    require_error(post(good, {{"axes", "1,0,0", "", ""}}), 400, "bad_measurement", "axes");
    require_error(post(good, {{"save_as", "twice", "", ""}}), 400, "bad_request", "save_as is given more than once");
    require_error(c.Post("/api/v1/calibrations", calibration_parts(good, {})), 400, "bad_request", "tool");
    require_error(c.Post("/api/v1/calibrations", calibration_parts(good, {{"tool_id", "999", "", ""}})), 404, "not_found",
                  "tool 999");
    require_error(c.Post("/api/v1/calibrations", httplib::MultipartFormDataItems{{"tool", tool_json().dump(), "", ""}}),
                  400, "bad_request", "part 'test' is missing");

    httplib::MultipartFormDataItems many{{"tool", tool_json().dump(), "", ""}, {"tests", "{}", "", ""}};
    for (int i = 0; i < 21; ++i) many.push_back({"test", "t,fx,fy,fz\n", fmt::format("t{}.csv", i), ""});
    require_error(c.Post("/api/v1/calibrations", many), 413, "too_many_tests", "limit is 20");

    REQUIRE(material_count(c) == 0);
}

TEST_CASE("calibration: steady-only drifting records with a steady window and a zero offset given per test") {
    // Slot records of the steady part only (no idle recording, no air between tooth passes), drifting
    // by 5 % of the mean force: each test gives its window (record time) and the amplifier's reading
    // with no load at the record's start (its channels).
    TestServer ts;
    auto c = ts.client(ts.write_key);
    TempDir dir;
    json conditions = json::object();
    httplib::MultipartFormDataItems items{{"tool", tool_json().dump(), "", ""}, {"axes", kSeedAxes, "", ""}};
    std::vector<std::pair<double, double>> windows;
    for (std::size_t i = 0; i < std::size(kFeedsPerTooth); ++i) {
        const double feed = kFeedsPerTooth[i];
        const auto cut = calib::straight_cut(feed, kAxialMm, calib::Side::Slot, 0, kRpm);
        fm::PredictOptions o;
        o.device = fm::Device::Cpu;
        calib::DynoOptions dyno;
        const auto [from_s, to_s] = calib::full_engagement_span_s(feed, kRpm);
        dyno.record_from_s = from_s;
        dyno.record_to_s = to_s;
        dyno.noise_rel = 0.005;
        dyno.drift_rel = {0.05, -0.05, 0.05};
        dyno.seed = 800 + static_cast<unsigned>(i);
        const std::string path = (dir.path() / "dyno.csv").string();
        const calib::DynoRecord rec = calib::write_dyno_file(fm::predict(cut.motion, cut.spec, o), path, dyno);
        std::ifstream in(path);
        const std::string file = fmt::format("steady{}.csv", i);
        items.push_back({"test", std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()),
                         file, "text/csv"});
        // A window inside the record, a few revolutions in from each end.
        windows.emplace_back(rec.t_first_s + 0.02, rec.t_last_s - 0.02);
        conditions[file] = {{"spindle_rpm", kRpm},
                            {"feed_mm_min", feed * calib::test_tool().flutes * kRpm},
                            {"axial_mm", kAxialMm},
                            {"mode", "slot"},
                            {"from_s", windows.back().first},
                            {"to_s", windows.back().second},
                            {"zero_N", rec.offset_at(rec.t_first_s, dyno)}};
    }
    auto post = [&](const json& cond) {
        auto parts = items;
        parts.push_back({"tests", cond.dump(), "", "application/json"});
        return c.Post("/api/v1/calibrations", parts);
    };
    auto r = post(conditions);
    REQUIRE(r->status == 200);
    const json got = body(r);
    INFO(got.dump());
    const auto want = fm::coefficients_of(calib::true_material());
    for (std::size_t k = 0; k < 6; ++k) {
        const double identified = got["material"][fm::kCoefficientKeys[k]].get<double>();
        INFO(fm::kCoefficientKeys[k] << ": identified " << identified << ", true " << want[k]);
        CHECK(std::abs(identified / want[k] - 1) < 0.03);
    }
    REQUIRE(got["tests"].size() == 3);
    for (std::size_t i = 0; i < 3; ++i) {
        const json& t = got["tests"][i];
        CHECK(t["window_source"] == "given");
        CHECK(t["zero_source"] == "given");
        CHECK(t["drift_source"] == "cut");
        CHECK(t["steady_from_s"].get<double>() >= windows[i].first - 1e-4);
        CHECK(t["steady_to_s"].get<double>() <= windows[i].second + 1e-4);
        CHECK(t["steady_to_s"].get<double>() - t["steady_from_s"].get<double>() >
              windows[i].second - windows[i].first - 2 * 60 / kRpm);
        // The drift is reported per axis, in N/s and over the window: the two agree.
        for (std::size_t ax = 0; ax < 3; ++ax)
            CHECK(t["drift_N"][ax].get<double>() ==
                  Approx(t["drift_N_per_s"][ax].get<double>() *
                         (t["steady_to_s"].get<double>() - t["steady_from_s"].get<double>())));
    }

    // Without zero_N nothing in these records tells the zero: 400 naming the key that gives it.
    json no_zero = conditions;
    no_zero["steady1.csv"].erase("zero_N");
    require_error(post(no_zero), 400, "bad_measurement", "zero_N in the conditions of 'steady1.csv'");
    json bad_zero = conditions;
    bad_zero["steady0.csv"]["zero_N"] = {1, 2};
    require_error(post(bad_zero), 400, "bad_request", "zero_N must be three numbers");
    json backwards = conditions;
    backwards["steady2.csv"]["to_s"] = backwards["steady2.csv"]["from_s"].get<double>() - 0.1;
    require_error(post(backwards), 400, "bad_request", "to_s must be after from_s");
    json outside = conditions;
    outside["steady0.csv"]["from_s"] = 50;
    outside["steady0.csv"]["to_s"] = 51;
    require_error(post(outside), 400, "bad_measurement", "no whole revolution in the steady window");
}
