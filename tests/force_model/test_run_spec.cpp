#include "force_model/force_model.hpp"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <cstdio>
#include <fstream>
#include <string>

using cutload::force_model::parse_run_spec;
using cutload::force_model::SpecError;
using cutload::force_model::ToolShape;
using nlohmann::json;

namespace {

json seed_spec() {
    return json::parse(R"({
      "tool": {"shape": "flat", "diameter_mm": 8, "flutes": 2, "helix_deg": 30,
               "corner_radius_mm": 0, "flute_length_mm": 20, "stickout_mm": 30,
               "holder": {"diameter_mm": 32, "length_mm": 40}},
      "material": {"name": "A7050", "Ktc_N_mm2": 796, "Krc_N_mm2": 168, "Kac_N_mm2": 222,
                   "Kte_N_mm": 27.7, "Kre_N_mm": 30.8, "Kae_N_mm": 1.4},
      "stock": {"box_mm": {"min": [0, 0, 0], "max": [105, 90, 30]}},
      "setup": {"offset_mm": [-200, 300, 350]},
      "limits": {"force_N": 800, "torque_Nm": 5, "power_kW": 5, "chip_mm": 0.3, "bending_MPa": 400},
      "resolution": {"angle_step_deg": 2, "axial_step_mm": 0.1, "grid_mm": 0.1}
    })");
}

// The message of the SpecError thrown by parsing j, or "" if it parsed.
std::string error_of(const json& j) {
    try {
        parse_run_spec(j);
    } catch (const SpecError& e) {
        return e.what();
    }
    return "";
}

}  // namespace

TEST_CASE("run spec: the seed's experiment parses with every value kept", "[spec]") {
    const auto spec = parse_run_spec(seed_spec());
    CHECK(spec.tool.shape == ToolShape::Flat);
    CHECK(spec.tool.diameter_mm == 8);
    CHECK(spec.tool.flutes == 2);
    CHECK(spec.tool.holder.diameter_mm == 32);
    CHECK(spec.material.Ktc_N_mm2 == 796);
    CHECK(spec.material.Kae_N_mm == 1.4);
    CHECK(spec.stock.max_mm[1] == 90);
    CHECK(spec.offset_mm[0] == -200);
    CHECK(spec.limits.chip_mm == 0.3);
    CHECK(spec.limits.rapid_feed_mm_min == 20000);  // documented default
    CHECK(spec.resolution.grid_mm == 0.1);
}

TEST_CASE("run spec: to_json round-trips", "[spec]") {
    const auto a = parse_run_spec(seed_spec());
    const auto b = parse_run_spec(cutload::force_model::to_json(a));
    CHECK(cutload::force_model::to_json(a) == cutload::force_model::to_json(b));
    CHECK(b.tool.stickout_mm == 30);
    CHECK(b.offset_mm[2] == 350);
}

TEST_CASE("run spec: optional sections take documented defaults", "[spec]") {
    json j = seed_spec();
    j.erase("setup");
    j.erase("limits");
    j.erase("resolution");
    j["tool"].erase("holder");
    const auto spec = parse_run_spec(j);
    CHECK(spec.offset_mm[0] == 0);
    CHECK(spec.limits.force_N == 0);
    CHECK(spec.resolution.angle_step_deg == 2);
    CHECK(spec.resolution.axial_step_mm == 0.1);
    CHECK(spec.tool.holder.diameter_mm == 0);
}

TEST_CASE("run spec: ball and bull corner radii", "[spec]") {
    json j = seed_spec();
    j["tool"]["shape"] = "ball";
    j["tool"].erase("corner_radius_mm");
    CHECK(parse_run_spec(j).tool.corner_radius_mm == 4);
    j["tool"]["corner_radius_mm"] = 3;
    CHECK_THAT(error_of(j), Catch::Contains("tool.corner_radius_mm") && Catch::Contains("diameter_mm / 2"));

    j["tool"]["shape"] = "bull";
    j["tool"]["corner_radius_mm"] = 1;
    CHECK(parse_run_spec(j).tool.shape == ToolShape::Bull);
    j["tool"].erase("corner_radius_mm");
    CHECK_THAT(error_of(j), Catch::Contains("tool.corner_radius_mm") && Catch::Contains("bull"));
}

TEST_CASE("run spec: errors name the key and what was expected", "[spec][errors]") {
    struct Case {
        const char* pointer;  // JSON pointer to change
        json value;           // new value (null erases)
        const char* key;      // key path the error must name
        const char* expect;   // part of the explanation
    };
    const Case cases[] = {
        {"/tool/diameter_mm", -8, "tool.diameter_mm", "(0, 200]"},
        {"/tool/diameter_mm", "8", "tool.diameter_mm", "expected a number"},
        {"/tool/flutes", 2.5, "tool.flutes", "whole number"},
        {"/tool/shape", "barrel", "tool.shape", "\"flat\", \"ball\", \"bull\""},
        {"/tool/helix_deg", 80, "tool.helix_deg", "[0, 70)"},
        {"/tool/stickout_mm", 10, "tool.stickout_mm", "at least flute_length_mm"},
        {"/tool/holder/diameter_mm", 6, "tool.holder.diameter_mm", "at least the tool diameter"},
        {"/tool/holder/colour", "red", "tool.holder.colour", "unknown key"},
        {"/material/Ktc_N_mm2", 0, "material.Ktc_N_mm2", "(0, 20000)"},
        {"/material/Kre_N_mm", -1, "material.Kre_N_mm", "[0, 1000)"},
        {"/stock/box_mm/max", json::array({105, 90}), "stock.box_mm.max", "array of 3 numbers"},
        {"/stock/box_mm/max", json::array({105, 0, 30}), "stock.box_mm.max", "along y"},
        {"/setup/offset_mm", json::array({0, "a", 0}), "setup.offset_mm[1]", "expected a number"},
        {"/limits/force_N", -5, "limits.force_N", ">= 0"},
        {"/resolution/grid_mm", 0.001, "resolution.grid_mm", "[0.005, 10]"},
        {"/resolution/grid_mm", 0.01, "resolution.grid_mm", "cells"},
        {"/resolution/angle_step_deg", 45, "resolution.angle_step_deg", "[0.1, 30]"},
        {"/diameter_mm", 8, "diameter_mm", "unknown key"},
    };
    for (const auto& c : cases) {
        json j = seed_spec();
        j[json::json_pointer(c.pointer)] = c.value;
        const std::string err = error_of(j);
        INFO("changed " << c.pointer << " -> " << err);
        CHECK_THAT(err, Catch::StartsWith(std::string(c.key) + ":") && Catch::Contains(c.expect));
    }
}

TEST_CASE("run spec: missing required keys are named", "[spec][errors]") {
    for (const char* pointer : {"/tool", "/material", "/stock/box_mm", "/tool/flutes", "/material/Kac_N_mm2",
                                "/tool/helix_deg", "/tool/stickout_mm"}) {
        json j = seed_spec();
        const json::json_pointer ptr(pointer);
        j[ptr.parent_pointer()].erase(ptr.back());
        std::string key = std::string(pointer).substr(1);
        for (auto& ch : key)
            if (ch == '/') ch = '.';
        CHECK(error_of(j) == key + ": required key is missing");
    }
    CHECK(error_of(json::array()) == "spec: expected a JSON object");
}

TEST_CASE("run spec: file errors name the file", "[spec][errors]") {
    const std::string path = "run_spec_test_bad.json";
    {
        std::ofstream out(path);
        out << "{\"tool\": {";
    }
    try {
        cutload::force_model::load_run_spec(path);
        FAIL("expected SpecError");
    } catch (const SpecError& e) {
        CHECK_THAT(e.what(), Catch::StartsWith(path + ": not valid JSON"));
    }
    std::remove(path.c_str());
    CHECK_THROWS_WITH(cutload::force_model::load_run_spec("no_such_spec.json"),
                      Catch::Contains("no_such_spec.json: cannot open"));
}
