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
        {"/tool/shape", "lollipop", "tool.shape", "\"flat\", \"ball\", \"bull\""},
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
        // Only a stock make_stock cannot build (over 4e8 rays) is the parser's; fewer cells are
        // a work limit of the front end (tests/app/test_work_bounds.cpp).
        {"/stock/box_mm/max", json::array({3000, 2000, 30}), "resolution.grid_mm", "cells"},
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
        // The tool's message goes on to name the other way to give tools (a table).
        CHECK(error_of(j).rfind(key + ": required key is missing", 0) == 0);
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
        // "file:line:column: key: not valid JSON: ..." (textio/json.hpp)
        CHECK_THAT(e.what(), Catch::StartsWith(path + ":1:") && Catch::Contains("not valid JSON"));
    }
    std::remove(path.c_str());
    CHECK_THROWS_WITH(cutload::force_model::load_run_spec("no_such_spec.json"),
                      Catch::Contains("no_such_spec.json: cannot open"));
}

namespace {

// The seed's spec with a tool table in place of its tool: a face mill, the seed's end mill and a
// drill, T1 with its own force limit.
json table_spec() {
    json j = seed_spec();
    json end_mill = j["tool"];
    j.erase("tool");
    json face = {{"number", 1},        {"shape", "bull"},        {"diameter_mm", 50},   {"flutes", 5},
                 {"helix_deg", 10},    {"corner_radius_mm", 0.8}, {"flute_length_mm", 6}, {"stickout_mm", 45},
                 {"limits", {{"force_N", 2000}, {"power_kW", 0}}}};
    end_mill["number"] = 11;
    json drill = {{"number", 3},         {"shape", "drill"},      {"diameter_mm", 6.35}, {"flutes", 2},
                  {"helix_deg", 30},     {"point_angle_deg", 118}, {"flute_length_mm", 70}, {"stickout_mm", 80}};
    j["tools"] = {face, end_mill, drill};
    return j;
}

}  // namespace

TEST_CASE("run spec: a tool table by T number, with per-tool limits over the run's", "[spec][tools]") {
    using cutload::force_model::find_tool;
    using cutload::force_model::limits_for;
    const auto spec = parse_run_spec(table_spec());
    CHECK_FALSE(spec.has_tool);
    REQUIRE(spec.tools.size() == 3);
    CHECK(spec.tools[0].number == 1);
    CHECK(spec.tools[0].tool.shape == ToolShape::Bull);
    CHECK(spec.tools[1].number == 11);
    CHECK(spec.tools[1].tool.holder.diameter_mm == 32);
    CHECK(spec.tools[2].tool.shape == ToolShape::Drill);
    CHECK(spec.tools[2].tool.point_angle_deg == 118);
    REQUIRE(find_tool(spec, 11) == &spec.tools[1]);
    CHECK(find_tool(spec, 2) == nullptr);
    CHECK(cutload::force_model::max_flutes(spec) == 5);

    // T1's own force limit and its power check switched off; the others stay the run's.
    const auto t1 = limits_for(spec.limits, spec.tools[0].limits);
    CHECK(t1.force_N == 2000);
    CHECK(t1.power_kW == 0);
    CHECK(t1.torque_Nm == 5);
    CHECK(t1.chip_mm == 0.3);
    const auto t11 = limits_for(spec.limits, spec.tools[1].limits);
    CHECK(t11.force_N == 800);
    CHECK(t11.power_kW == 5);

    // Round trip: the table, its overrides (only those given), no "tool".
    const json back = cutload::force_model::to_json(spec);
    CHECK_FALSE(back.contains("tool"));
    CHECK(back["tools"][0]["limits"] == json({{"force_N", 2000}, {"power_kW", 0}}));
    CHECK_FALSE(back["tools"][1].contains("limits"));
    CHECK(back["tools"][2]["point_angle_deg"] == 118);
    CHECK(cutload::force_model::to_json(parse_run_spec(back)) == back);

    // Beside a tool: both kept.
    json both = table_spec();
    both["tool"] = seed_spec()["tool"];
    const auto b = parse_run_spec(both);
    CHECK(b.has_tool);
    CHECK(b.tools.size() == 3);
    CHECK(cutload::force_model::to_json(b).contains("tool"));
}

TEST_CASE("run spec: tool table errors name the entry and key", "[spec][tools][errors]") {
    auto with = [](auto change) {
        json j = table_spec();
        change(j);
        return error_of(j);
    };
    CHECK(with([](json& j) { j["tools"][2]["diameter_mm"] = -1; }) == "tools[2].diameter_mm: must be in (0, 200] mm");
    CHECK(with([](json& j) { j["tools"][1].erase("flutes"); }) == "tools[1].flutes: required key is missing");
    CHECK(with([](json& j) { j["tools"][2]["number"] = 1; }) == "tools[2].number: T1 is already tools[0]");
    CHECK(with([](json& j) { j["tools"][0]["number"] = 1.5; }) == "tools[0].number: must be a whole T number from 0 to 99999999");
    CHECK(with([](json& j) { j["tools"][0].erase("number"); }) == "tools[0].number: required key is missing");
    CHECK(with([](json& j) { j["tools"][1]["diamter_mm"] = 8; }) == "tools[1].diamter_mm: unknown key");
    CHECK(with([](json& j) { j["tools"][0]["limits"]["force_N"] = -5; }) ==
          "tools[0].limits.force_N: must be >= 0 (0 disables the check for this tool)");
    CHECK(with([](json& j) { j["tools"][0]["limits"]["rapid_feed_mm_min"] = 9000; }) ==
          "tools[0].limits.rapid_feed_mm_min: the rapid feed is the machine's: set it in the run's limits");
    CHECK(with([](json& j) { j["tools"][0]["limits"]["forse_N"] = 1; }) == "tools[0].limits.forse_N: unknown key");
    CHECK(with([](json& j) { j["tools"] = json::array(); }) == "tools: must list at least one tool (or leave the key out)");
    CHECK(with([](json& j) { j["tools"] = json::object(); }).rfind("tools: expected an array", 0) == 0);
    CHECK(with([](json& j) { j["tools"][1] = 7; }) == "tools[1]: expected a JSON object");
    CHECK(with([](json& j) { j.erase("tools"); }) == "tool: required key is missing (or give a tool table, \"tools\")");
}

TEST_CASE("run spec: drills and chamfer tools are cones with a point angle", "[spec][tools]") {
    json j = seed_spec();
    j["tool"] = {{"shape", "chamfer"}, {"diameter_mm", 10},    {"flutes", 4},         {"helix_deg", 0},
                 {"point_angle_deg", 90}, {"tip_diameter_mm", 1}, {"flute_length_mm", 12}, {"stickout_mm", 30}};
    const auto spec = parse_run_spec(j);
    CHECK(spec.tool.shape == ToolShape::Chamfer);
    CHECK(spec.tool.tip_diameter_mm == 1);
    CHECK(cutload::force_model::to_json(spec)["tool"] == j["tool"]);

    auto with = [&](auto change) {
        json k = j;
        change(k);
        return error_of(k);
    };
    // The cone (R - r_tip) / tan(45 deg) = 4.5 mm high must fit in the flutes.
    CHECK(with([](json& k) { k["tool"]["flute_length_mm"] = 4; }) ==
          "tool.flute_length_mm: must be at least the cone's height, 4.5 mm (the point widens to diameter_mm there)");
    CHECK(with([](json& k) { k["tool"].erase("point_angle_deg"); }) == "tool.point_angle_deg: required key is missing");
    CHECK(with([](json& k) { k["tool"]["point_angle_deg"] = 180; }).rfind("tool.point_angle_deg: must be in [20, 170] degrees", 0) == 0);
    CHECK(with([](json& k) { k["tool"]["tip_diameter_mm"] = 10; }) == "tool.tip_diameter_mm: must be in [0, diameter_mm) mm");
    CHECK(with([](json& k) { k["tool"]["corner_radius_mm"] = 1; }) ==
          "tool.corner_radius_mm: must be 0 for a drill or chamfer tool (a cone)");
    CHECK(with([](json& k) {
              k["tool"]["shape"] = "drill";
          }) == "tool.tip_diameter_mm: only a chamfer tool has a flat tip (a drill's point is sharp)");
    CHECK(with([](json& k) {
              k["tool"] = seed_spec()["tool"];
              k["tool"]["point_angle_deg"] = 118;
          }) == "tool.point_angle_deg: only for a drill or chamfer tool");
}

TEST_CASE("run spec: 1e400 anywhere names file, line, column and key (issue 19)", "[spec][errors]") {
    using cutload::force_model::parse_run_spec_text;
    // Each key of the seed spec in turn, the number replaced by one beyond a double.
    for (const std::string key : {"tool.diameter_mm", "material.Ktc_N_mm2", "limits.force_N", "resolution.grid_mm"}) {
        json j = seed_spec();
        const auto dot = key.find('.');
        j[key.substr(0, dot)][key.substr(dot + 1)] = 12345.678;
        std::string text = j.dump(2);
        const auto at = text.find("12345.678");
        REQUIRE(at != std::string::npos);
        text.replace(at, 9, "1e400");
        try {
            parse_run_spec_text(text, "RUN.json");
            FAIL("parsed " << key);
        } catch (const SpecError& e) {
            INFO(e.what());
            CHECK_THAT(e.what(), Catch::StartsWith("RUN.json:") && Catch::Contains(": " + key + ": the number 1e400 is out of range"));
            CHECK(std::string(e.what()).find('\n') == std::string::npos);
        }
    }
    json j = seed_spec();
    std::string text = j.dump();
    text.replace(text.find("[105,90,30]"), 11, "[105,-1e999,30]");
    CHECK_THROWS_WITH(parse_run_spec_text(text, "RUN.json"), Catch::Contains("stock.box_mm.max[1]: the number -1e999"));
    // The text and the parsed document give the same spec.
    CHECK(cutload::force_model::to_json(parse_run_spec_text(seed_spec().dump(), "RUN.json")) ==
          cutload::force_model::to_json(parse_run_spec(seed_spec())));
}

TEST_CASE("run spec: stock corners and the setup offset lie within 100 m of machine zero", "[spec][errors]") {
    json j = seed_spec();
    j["setup"]["offset_mm"] = {-200, 1e300, 350};
    CHECK(error_of(j) == "setup.offset_mm[1]: must be within +-100000 mm, got 1e+300");
    j = seed_spec();
    j["stock"]["box_mm"]["min"] = {-1e6, 0, 0};
    CHECK(error_of(j) == "stock.box_mm.min[0]: must be within +-100000 mm, got -1e+06");
    j = seed_spec();
    j["setup"]["offset_mm"] = {-99999, 99999, 0};
    CHECK(error_of(j).empty());
}

TEST_CASE("run spec: a tapered end mill is named by its half angle, the diameter at its tip", "[spec][tools]") {
    json j = seed_spec();
    j["tool"]["taper_deg"] = 3;
    const auto spec = parse_run_spec(j);
    CHECK(spec.tool.taper_deg == 3);
    CHECK(spec.tool.diameter_mm == 8);
    CHECK(cutload::force_model::to_json(spec)["tool"] == j["tool"]);
    // Untapered tools are written as before: no taper_deg key.
    CHECK_FALSE(cutload::force_model::to_json(parse_run_spec(seed_spec()))["tool"].contains("taper_deg"));
    json zero = seed_spec();
    zero["tool"]["taper_deg"] = 0;
    CHECK(cutload::force_model::to_json(parse_run_spec(zero)) == cutload::force_model::to_json(parse_run_spec(seed_spec())));
    // A tapered ball: the ball's diameter is the tip's.
    json ball = seed_spec();
    ball["tool"]["shape"] = "ball";
    ball["tool"]["corner_radius_mm"] = 4;
    ball["tool"]["taper_deg"] = 1.5;
    CHECK(parse_run_spec(ball).tool.taper_deg == 1.5);

    auto with = [&](auto change) {
        json k = j;
        change(k);
        return error_of(k);
    };
    CHECK(with([](json& k) { k["tool"]["taper_deg"] = -1; }) ==
          "tool.taper_deg: must be in [0, 15] degrees per side (the half angle of the flank; 0: no taper)");
    CHECK(with([](json& k) { k["tool"]["taper_deg"] = 16; }) ==
          "tool.taper_deg: must be in [0, 15] degrees per side (the half angle of the flank; 0: no taper)");
    CHECK(with([](json& k) { k["tool"]["taper_deg"] = "3"; }) == "tool.taper_deg: expected a number");
    // The holder must clear the flutes' top: 8 + 2 x 20 tan(3 deg) = 10.10 mm.
    CHECK(with([](json& k) { k["tool"]["holder"]["diameter_mm"] = 10; }) ==
          "tool.holder.diameter_mm: must be at least the tapered tool's diameter at the end of its flutes and at "
          "most 500 mm");
    CHECK(with([](json& k) { k["tool"]["holder"]["diameter_mm"] = 10.2; }).empty());
    // 150 mm tip + 2 x 300 tan(15 deg) = 310.8 mm where the flutes end.
    CHECK(with([](json& k) {
              k["tool"]["diameter_mm"] = 150;
              k["tool"]["taper_deg"] = 15;
              k["tool"]["flute_length_mm"] = 300;
              k["tool"]["stickout_mm"] = 400;
              k["tool"].erase("holder");
          }).rfind("tool.flute_length_mm: with taper_deg 15 the flutes end at a diameter of 310.7", 0) == 0);
    CHECK(with([](json& k) {
              k["tool"] = {{"shape", "drill"}, {"diameter_mm", 8},      {"flutes", 2},      {"helix_deg", 30},
                           {"point_angle_deg", 118}, {"taper_deg", 2}, {"flute_length_mm", 20}, {"stickout_mm", 30}};
          }) == "tool.taper_deg: only for a flat, ball or bull end mill (a drill's or chamfer tool's cone is point_angle_deg)");
    // In a tool table too, named by entry.
    json table = seed_spec();
    json entry = table["tool"];
    entry["number"] = 7;
    entry["taper_deg"] = 20;
    table.erase("tool");
    table["tools"] = json::array({entry});
    CHECK(error_of(table).rfind("tools[0].taper_deg: must be in [0, 15] degrees per side", 0) == 0);
}

TEST_CASE("run spec: a barrel tool is named by its widest diameter, barrel radius and tip ball radius", "[spec][tools]") {
    // Document 003's tool: r 3, r1 96, r2 1 mm; its widest point is 20.391 mm above the tip.
    json j = seed_spec();
    j["tool"] = {{"shape", "barrel"},       {"diameter_mm", 6},      {"flutes", 4},         {"helix_deg", 30},
                 {"barrel_radius_mm", 96}, {"tip_radius_mm", 1},     {"flute_length_mm", 22}, {"stickout_mm", 40},
                 {"holder", {{"diameter_mm", 25}, {"length_mm", 50}}}};
    const auto spec = parse_run_spec(j);
    CHECK(spec.tool.shape == cutload::force_model::ToolShape::Barrel);
    CHECK(spec.tool.barrel_radius_mm == 96);
    CHECK(spec.tool.tip_radius_mm == 1);
    CHECK(spec.tool.corner_radius_mm == 0);
    CHECK(cutload::force_model::to_json(spec)["tool"] == j["tool"]);

    auto with = [&](auto change) {
        json k = j;
        change(k);
        return error_of(k);
    };
    // r1 must pass the widest radius (the arc's centre lies across the axis).
    const std::string r1_rule =
        "tool.barrel_radius_mm: must be greater than diameter_mm / 2 (the flank arc's centre lies across the axis) "
        "and at most 10000 mm";
    CHECK(with([](json& k) { k["tool"]["barrel_radius_mm"] = 2.5; }) == r1_rule);
    CHECK(with([](json& k) { k["tool"]["barrel_radius_mm"] = 3; }) == r1_rule);
    CHECK(with([](json& k) { k["tool"]["barrel_radius_mm"] = 20000; }) == r1_rule);
    // r1 10 m with a 200 mm tool and a 1 mm tip: 1 + sqrt(99 x 19899) = 1404.6 mm to the widest point.
    CHECK(with([](json& k) {
              k["tool"]["diameter_mm"] = 200;
              k["tool"]["barrel_radius_mm"] = 10000;
              k["tool"]["holder"]["diameter_mm"] = 250;
          }) == "tool.barrel_radius_mm: puts the barrel's widest point 1404.6 mm above the tip, beyond the longest "
                "flutes (500 mm): a smaller barrel radius");
    CHECK(with([](json& k) { k["tool"].erase("barrel_radius_mm"); }) == "tool.barrel_radius_mm: required key is missing");
    const std::string r2_rule =
        "tool.tip_radius_mm: must be in (0, diameter_mm / 2) mm (the tip ball, centred on the axis, inside the barrel)";
    CHECK(with([](json& k) { k["tool"]["tip_radius_mm"] = 3; }) == r2_rule);
    CHECK(with([](json& k) { k["tool"]["tip_radius_mm"] = 0; }) == r2_rule);
    CHECK(with([](json& k) { k["tool"]["tip_radius_mm"] = "1"; }) == "tool.tip_radius_mm: expected a number");
    // The flutes must reach the widest point: 1 + sqrt(376) = 20.3907 mm, named rounded up.
    CHECK(with([](json& k) { k["tool"]["flute_length_mm"] = 20; }) ==
          "tool.flute_length_mm: must reach the barrel's widest point, 20.391 mm above the tip (where the arc of "
          "barrel_radius_mm from the tip ball reaches diameter_mm)");
    CHECK(with([](json& k) { k["tool"]["flute_length_mm"] = 20.391; }).empty());
    CHECK(with([](json& k) { k["tool"]["holder"]["diameter_mm"] = 5.9; }) ==
          "tool.holder.diameter_mm: must be at least the tool diameter and at most 500 mm");
    // Other shapes' keys are refused on a barrel, and the barrel's on other shapes.
    CHECK(with([](json& k) { k["tool"]["corner_radius_mm"] = 1; }) ==
          "tool.corner_radius_mm: not for a barrel tool (its tip ball is tip_radius_mm)");
    CHECK(with([](json& k) { k["tool"]["taper_deg"] = 2; }) ==
          "tool.taper_deg: only for a flat, ball or bull end mill (a barrel's flank is barrel_radius_mm)");
    CHECK(with([](json& k) { k["tool"]["point_angle_deg"] = 90; }) == "tool.point_angle_deg: only for a drill or chamfer tool");
    json flat = seed_spec();
    flat["tool"]["barrel_radius_mm"] = 96;
    CHECK(error_of(flat) == "tool.barrel_radius_mm: only for a barrel tool");
    flat = seed_spec();
    flat["tool"]["tip_radius_mm"] = 1;
    CHECK(error_of(flat) == "tool.tip_radius_mm: only for a barrel tool");
    // In a tool table too, named by entry.
    json table = j;
    json entry = table["tool"];
    entry["number"] = 3;
    entry["tip_radius_mm"] = 4;
    table.erase("tool");
    table["tools"] = json::array({entry});
    CHECK(error_of(table).rfind("tools[0].tip_radius_mm: must be in (0, diameter_mm / 2) mm", 0) == 0);
}
