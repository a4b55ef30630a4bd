// Machines for the machine/ tests: the two bundled definitions and two head-head machines written
// here (one with a 45 deg nutating axis and pivots off the spindle line, to exercise the general
// inverse kinematics).
#pragma once

#include "machine/kinematics.hpp"
#include "machine/machine.hpp"

#include <nlohmann/json.hpp>

#include <cmath>
#include <string>

namespace machine_fixtures {

using cutload::machine::Machine;

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180;

inline std::string data_path(const std::string& file) { return std::string(CUTLOAD_SOURCE_DIR) + "/data/machines/" + file; }

inline Machine ac_table_table() { return cutload::machine::load_machine(data_path("ac_table_table.json")); }
inline Machine bc_head_table() { return cutload::machine::load_machine(data_path("bc_head_table.json")); }

// A fork head on a gantry: C about the vertical, A about X below it, the A line 180 mm above the
// gauge point and 25 mm off the spindle line in Y (an offset head).
inline Machine ca_head_head() {
    return cutload::machine::parse_machine(nlohmann::json::parse(R"({
      "name": "CA head-head with an offset fork",
      "code": "b X Y Z C A t",
      "axes": {"C": {"pivot_mm": [0, 0, 400], "limits_deg": [-360, 360]},
               "A": {"pivot_mm": [0, 25, 180], "limits_deg": [-105, 105]}},
      "spindle": {"gauge_point_mm": [0, 0, 0], "axis": [0, 0, 1], "x_direction": [1, 0, 0]}
    })"));
}

// A nutating head: C vertical, then B' at 45 deg in the Y-Z plane, pivots off every line, the
// linear axes in an unusual order and one of them with sense -1.
inline Machine nutating_head_head() {
    const double s = std::sqrt(0.5);
    nlohmann::json j = nlohmann::json::parse(R"({
      "name": "nutating head-head",
      "workpiece_side": [],
      "tool_side": [
        {"name": "Y", "type": "linear", "direction": [0, 1, 0], "limits_mm": [-600, 0]},
        {"name": "Z", "type": "linear", "direction": [0, 0, 1], "limits_mm": [-500, 0], "sense": -1},
        {"name": "X", "type": "linear", "direction": [1, 0, 0], "limits_mm": [-800, 0]},
        {"name": "C", "type": "rotary", "direction": [0, 0, 1], "pivot_mm": [12, -7, 300]},
        {"name": "B", "type": "rotary", "direction": [0, 0, 0], "pivot_mm": [3, 40, 150], "limits_deg": [-5, 185]}
      ],
      "spindle": {"gauge_point_mm": [0, 0, 0], "axis": [0, 0, 1], "x_direction": [1, 0, 0]}
    })");
    j["tool_side"][4]["direction"] = {0, -s, s};
    return cutload::machine::parse_machine(j);
}

}  // namespace machine_fixtures
