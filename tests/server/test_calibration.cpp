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
