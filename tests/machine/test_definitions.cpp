// Machine definitions: the bundled examples, the form-shaping code, geometric-error keys and the
// error messages for bad definitions (each names the key a person has to fix).
#include "machine_fixtures.hpp"

#include <catch2/catch.hpp>

#include <cstdio>
#include <fstream>
#include <functional>
#include <vector>

using namespace cutload::machine;
using machine_fixtures::data_path;
using nlohmann::json;

namespace {

// The message of the MachineError thrown by parsing j, or "" if it parsed.
std::string error_of(const json& j) {
    try {
        parse_machine(j);
    } catch (const MachineError& e) {
        return e.what();
    }
    return "";
}

json ac_json() {
    std::ifstream in(data_path("ac_table_table.json"));
    return json::parse(in);
}

json code_json() {
    return json::parse(R"({
      "code": "C A b Y X Z t",
      "axes": {"C": {"pivot_mm": [0, 0, 0]}, "A": {"pivot_mm": [0, 0, -100], "limits_deg": [-120, 30]}}
    })");
}

}  // namespace

TEST_CASE("the bundled AC table-table machine loads with its chain from the workpiece to the tool", "[machine]") {
    const Machine m = machine_fixtures::ac_table_table();
    CHECK(m.kind() == MachineKind::TableTable);
    REQUIRE(m.chain.size() == 5);
    const std::string order = {m.chain[0].name, m.chain[1].name, m.chain[2].name, m.chain[3].name, m.chain[4].name};
    CHECK(order == "CAYXZ");   // document 000's example machine, code 64213
    CHECK(m.chain[0].side == Side::Workpiece);
    CHECK(m.chain[1].side == Side::Workpiece);
    CHECK(m.chain[2].side == Side::Tool);
    const Axis& a = m.chain[m.index_of('A')];
    CHECK(a.rotary());
    CHECK(a.lower == -120);
    CHECK(a.upper == 30);
    CHECK(a.pivot_mm.isApprox(Eigen::Vector3d(-350, -275, -560)));
    CHECK(a.channel == "a");
    CHECK(std::isinf(m.chain[m.index_of('C')].upper));   // a continuous C table
    CHECK_FALSE(m.has_errors());
}

TEST_CASE("the bundled BC head-table machine, written as a form-shaping code, loads", "[machine]") {
    const Machine m = machine_fixtures::bc_head_table();
    CHECK(m.kind() == MachineKind::HeadTable);
    REQUIRE(m.chain.size() == 5);
    CHECK(m.chain[0].name == 'C');
    CHECK(m.chain[0].side == Side::Workpiece);
    CHECK(m.chain[4].name == 'B');
    CHECK(m.chain[4].side == Side::Tool);
    CHECK(m.chain[4].direction == Eigen::Vector3d::UnitY());   // B turns about Y
    CHECK(m.chain[4].pivot_mm.z() == 230);                      // pivot distance above the gauge point
    CHECK(m.chain[m.index_of('X')].lower == -1200);
}

TEST_CASE("machine kinds follow where the rotary axes sit, and positions name their axes", "[machine]") {
    const Machine hh = machine_fixtures::ca_head_head();
    CHECK(hh.kind() == MachineKind::HeadHead);
    CHECK(std::string(kind_name(hh.kind())) == "head-head");
    // No axis on the workpiece side: the bed frame is the workpiece frame.
    const Frame bed = bed_to_workpiece(hh, positions(hh, {{'X', -10}, {'C', 40}, {'A', 30}}));
    CHECK(bed.R == Eigen::Matrix3d::Identity());
    CHECK(bed.origin_mm == Eigen::Vector3d::Zero());
    CHECK(parse_machine(json::parse(R"({"code": "b X Y Z t"})")).kind() == MachineKind::ThreeAxis);
    CHECK(parse_machine(json::parse(R"({"code": "A b X Y Z t", "axes": {"A": {"pivot_mm": [0, 0, 0]}}})")).kind() ==
          MachineKind::FourAxisTable);
    CHECK_THROWS_WITH(positions(hh, {{'B', 10}}), "machine \"CA head-head with an offset fork\" has no axis B");
}

TEST_CASE("a form-shaping code and the explicit form give the same chain", "[machine]") {
    json explicit_form = json::parse(R"({
      "workpiece_side": [
        {"name": "C", "type": "rotary", "direction": [0, 0, 1], "pivot_mm": [0, 0, 0]},
        {"name": "A", "type": "rotary", "direction": [1, 0, 0], "pivot_mm": [0, 0, -100], "limits_deg": [-120, 30]}],
      "tool_side": [
        {"name": "Y", "type": "linear", "direction": [0, 1, 0]},
        {"name": "X", "type": "linear", "direction": [1, 0, 0]},
        {"name": "Z", "type": "linear", "direction": [0, 0, 1]}]
    })");
    const Machine a = parse_machine(explicit_form);
    for (const std::string code : {"C A b Y X Z t", "w C A b Y X Z t", "CAbYXZ", "w64b213t", "6 4 b 2 1 3"}) {
        json j = code_json();
        j["code"] = code;
        const Machine b = parse_machine(j);
        INFO(code);
        REQUIRE(b.chain.size() == a.chain.size());
        for (std::size_t i = 0; i < a.chain.size(); ++i) {
            CHECK(b.chain[i].name == a.chain[i].name);
            CHECK(b.chain[i].type == a.chain[i].type);
            CHECK(b.chain[i].side == a.chain[i].side);
            CHECK(b.chain[i].direction == a.chain[i].direction);
            CHECK(b.chain[i].pivot_mm == a.chain[i].pivot_mm);
            CHECK(b.chain[i].lower == a.chain[i].lower);
        }
    }
}

TEST_CASE("geometric errors read ISO 230-1 names with units, constants and tables", "[machine]") {
    Machine m = machine_fixtures::ac_table_table();
    load_errors(m, data_path("ac_table_table_errors.json"));
    CHECK(m.has_errors());
    const AxisErrors& x = m.chain[m.index_of('X')].errors;
    REQUIRE(x.component[kErrX]);
    // EXX_um table: -400 -> 3.1 um, -450 halfway between 4.0 and 3.1 um; beyond the table the end holds.
    CHECK((*x.component[kErrX])(-400) == Approx(3.1e-3));
    CHECK((*x.component[kErrX])(-450) == Approx(3.55e-3));
    CHECK((*x.component[kErrX])(-800) == Approx(6.1e-3));
    CHECK(x.location[kErrC] == Approx(12e-6));                 // EC0X_urad
    const AxisErrors& c = m.chain[m.index_of('C')].errors;
    CHECK(c.location[kErrY] == Approx(-9e-3));                 // EY0C_um
    REQUIRE(c.component[kErrC]);
    CHECK(c.component[kErrC]->periodic);                       // 0..360 deg
    const double arcsec = machine_fixtures::kDeg / 3600;
    CHECK((*c.component[kErrC])(45) == Approx(2.5 * arcsec));
    CHECK((*c.component[kErrC])(405) == Approx(2.5 * arcsec));   // one turn on: the same error
    CHECK((*c.component[kErrC])(-45) == Approx(-1.4 * arcsec));  // = 315 deg
    CHECK((*c.component[kErrC])(22.5) == Approx(1.25 * arcsec));
    CHECK(c.reference_point_mm == m.chain[m.index_of('C')].pivot_mm);   // rotations act about the pivot
    const AxisErrors& a = m.chain[m.index_of('A')].errors;
    REQUIRE(a.component[kErrA]);
    CHECK_FALSE(a.component[kErrA]->periodic);                 // -120..30 deg: held at the ends
    CHECK((*a.component[kErrA])(-130) == Approx(-6 * arcsec));
}

TEST_CASE("bad machine definitions are refused with the key named", "[machine]") {
    struct Case {
        const char* what;
        std::function<void(json&)> edit;
        std::string message;   // the start of the expected message
    };
    const std::vector<Case> cases = {
        {"no chain", [](json& j) { j.erase("workpiece_side"); j.erase("tool_side"); },
         "a machine needs its chain"},
        {"a direction that is not a unit vector", [](json& j) { j["tool_side"][1]["direction"] = {0, 1, 1}; },
         "tool_side[1].direction: must be a unit vector (its length is 1.41421)"},
        {"a direction with a string", [](json& j) { j["tool_side"][1]["direction"] = {0, "1", 0}; },
         "tool_side[1].direction[1]: expected a number"},
        {"a rotary axis without a pivot", [](json& j) { j["workpiece_side"][0].erase("pivot_mm"); },
         "workpiece_side[0].pivot_mm: required key is missing"},
        {"a linear axis with a pivot", [](json& j) { j["tool_side"][0]["pivot_mm"] = {0, 0, 0}; },
         "tool_side[0].pivot_mm: linear axis Y has no pivot"},
        {"a letter of the wrong type", [](json& j) { j["workpiece_side"][1]["type"] = "linear"; },
         "workpiece_side[1].type: axis A is rotary"},
        {"an unknown type", [](json& j) { j["workpiece_side"][1]["type"] = "swivel"; },
         "workpiece_side[1].type: expected \"linear\" or \"rotary\", got \"swivel\""},
        {"a misspelt key", [](json& j) { j["workpiece_side"][1]["pviot_mm"] = {0, 0, 0}; },
         "workpiece_side[1].pviot_mm: unknown key"},
        {"degrees on a linear axis", [](json& j) { j["tool_side"][0]["limits_deg"] = {-10, 10}; },
         "tool_side[0].limits_deg: linear axis Y takes limits_mm"},
        {"limits upside down", [](json& j) { j["workpiece_side"][1]["limits_deg"] = {30, -120}; },
         "workpiece_side[1].limits_deg: lower must be below upper"},
        {"a sense of 2", [](json& j) { j["workpiece_side"][0]["sense"] = 2; },
         "workpiece_side[0].sense: must be 1 or -1"},
        {"an axis twice", [](json& j) { j["tool_side"][2]["name"] = "X"; },
         "workpiece_side, tool_side: axis X appears twice"},
        {"two linear axes", [](json& j) { j["tool_side"].erase(2); },
         "workpiece_side, tool_side: needs exactly three linear axes (X, Y, Z), has 2"},
        {"linear axes in one plane", [](json& j) { j["tool_side"][2]["direction"] = {0.6, 0.8, 0}; },
         "workpiece_side, tool_side: the directions of the linear axes must span space"},
        {"parallel rotary axes", [](json& j) { j["workpiece_side"][1]["direction"] = {0, 0, 1}; },
         "workpiece_side, tool_side: rotary axes C and A are parallel"},
        {"both forms at once", [](json& j) { j["code"] = "C A b Y X Z t"; },
         "code: give the chain either as a code or as workpiece_side and tool_side, not both"},
        {"a spindle x along its axis", [](json& j) { j["spindle"]["x_direction"] = {0, 0, 1}; },
         "spindle.x_direction: must not be parallel to the spindle axis"},
        {"an unknown top-level key", [](json& j) { j["kinematics"] = "trt"; }, "kinematics: unknown key"},
        {"an error without a unit", [](json& j) { j["errors"]["X"]["EXX"] = 1; },
         "errors.X.EXX: needs a unit suffix: _mm or _um"},
        {"an error in a unit that does not fit", [](json& j) { j["errors"]["X"]["EAX_um"] = 1; },
         "errors.X.EAX_um: unit 'um' does not fit a rotation"},
        {"an error filed under the wrong axis", [](json& j) { j["errors"]["X"]["EXY_um"] = 1; },
         "errors.X.EXY_um: names axis Y, but it is listed under axis X"},
        {"an error given twice", [](json& j) { j["errors"]["C"] = {{"ECC_arcsec", 1}, {"ECC_urad", 5}}; },
         "errors.C.ECC_urad: the same error is already given as ECC_arcsec"},
        {"an error name that is no error", [](json& j) { j["errors"]["X"]["straightness_um"] = 1; },
         "errors.X.straightness_um: unknown key: expected an ISO 230-1 error name"},
        {"errors of an axis the machine lacks", [](json& j) { j["errors"]["B"] = json::object(); },
         "errors.B: is not an axis of this machine"},
        {"a position for a linear axis", [](json& j) { j["errors"]["X"]["EY0X_um"] = 3; },
         "errors.X.EY0X_um: a linear axis has no position"},
        {"a table whose positions go back", [](json& j) {
             j["errors"]["X"]["EXX_um"] = {{"at_mm", {0, -100, -200}}, {"values", {0, 1, 2}}}; },
         "errors.X.EXX_um.at_mm[1]: positions must increase strictly"},
        {"a table with too few values", [](json& j) {
             j["errors"]["X"]["EXX_um"] = {{"at_mm", {-200, -100, 0}}, {"values", {0, 1}}}; },
         "errors.X.EXX_um.values: expected an array of 3 numbers, one per position"},
        {"a rotary table in mm", [](json& j) {
             j["errors"]["C"]["ECC_arcsec"] = {{"at_mm", {0, 360}}, {"values", {0, 0}}}; },
         "errors.C.ECC_arcsec.at_deg: required key is missing"},
        {"a full-turn table that does not close", [](json& j) {
             j["errors"]["C"]["ECC_arcsec"] = {{"at_deg", {0, 180, 360}}, {"values", {0, 3, 1}}}; },
         "errors.C.ECC_arcsec.values: a table over one full turn must end with the value it starts with"},
        {"a location error as a table", [](json& j) {
             j["errors"]["C"]["EX0C_um"] = {{"at_deg", {0, 360}}, {"values", {0, 0}}}; },
         "errors.C.EX0C_um: a location error is a constant: expected a number"},
        {"a reference point off the rotary axis", [](json& j) {
             j["errors"]["C"]["reference_point_mm"] = {-340, -275, 0}; },
         "errors.C.reference_point_mm: must lie on the C axis line (it is 10 mm off it)"},
    };
    for (const Case& c : cases) {
        json j = ac_json();
        c.edit(j);
        INFO(c.what);
        const std::string msg = error_of(j);
        CHECK(msg.rfind(c.message, 0) == 0);
        if (msg.rfind(c.message, 0) != 0) WARN("got: " << msg);
    }
    CHECK(error_of(json::array()) == "expected a JSON object");
}

TEST_CASE("bad form-shaping codes are refused with the position named", "[machine]") {
    const std::vector<std::pair<std::string, std::string>> cases = {
        {"C A Y X Z t", "code: has no bed 'b'"},
        {"C A b Y X Q t", "code: 'Q' at position 11: expected an axis letter X Y Z A B C, a motion digit 1-6, or w, b, t"},
        {"C A b Y X C Z", "code: 'C' at position 11: axis C appears twice"},
        {"C A b b Y X Z", "code: 'b' at position 7: the bed 'b' appears twice"},
        {"C w A b Y X Z", "code: 'w' at position 3: the workpiece 'w' must come first"},
        {"C A b Y X t Z", "code: 'Z' at position 13 follows the tool 't'"},
        {"C A b Y X 7", "code: '7' at position 11: expected an axis letter"},
    };
    for (const auto& [code, message] : cases) {
        json j = code_json();
        j["code"] = code;
        INFO(code);
        const std::string msg = error_of(j);
        CHECK(msg.rfind(message, 0) == 0);
        if (msg.rfind(message, 0) != 0) WARN("got: " << msg);
    }
    json j = code_json();
    j["axes"]["A"]["direction"] = {1, 0, 0};
    CHECK(error_of(j).rfind("axes.A.direction: is set by the code", 0) == 0);
    j = code_json();
    j["axes"]["B"] = {{"limits_deg", {0, 90}}};
    CHECK(error_of(j) == "axes.B: is not an axis of the code");
    j = code_json();
    j["axes"].erase("C");
    CHECK(error_of(j) == "axes.C: rotary axis C needs its pivot_mm");
}

TEST_CASE("machine and error files name the file in their errors", "[machine]") {
    const std::string missing = data_path("no_such_machine.json");
    CHECK_THROWS_WITH(load_machine(missing), missing + ": cannot open the file");
    const std::string bad = "machine_bad_test.json";
    {
        std::ofstream out(bad);
        out << R"({"code": "C A b Y X Z t", "axes": {"C": {"pivot_mm": [0, 0]}}})";
    }
    CHECK_THROWS_WITH(load_machine(bad), bad + ": axes.C.pivot_mm: expected an array of 3 numbers [x, y, z]");
    {
        std::ofstream out(bad);
        out << R"({"code": "C A b Y X Z t",)";
    }
    CHECK_THROWS_WITH(load_machine(bad), Catch::Matchers::StartsWith(bad + ": not valid JSON"));
    {
        std::ofstream out(bad);
        out << R"({"X": {"EXX_um": 1}, "C": {"ECC_deg": "a lot"}})";
    }
    Machine m = machine_fixtures::ac_table_table();
    CHECK_THROWS_WITH(load_errors(m, bad), Catch::Matchers::StartsWith(bad + ": C.ECC_deg: expected a number"));
    CHECK_FALSE(m.has_errors());   // nothing half-applied
    std::remove(bad.c_str());
}
