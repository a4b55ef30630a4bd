// Public interface of machine/: machine definitions (the kinematic chain from the workpiece to the
// tool, with optional geometric errors), read from JSON. Kinematics and velocities are in
// machine/kinematics.hpp and machine/twist.hpp. Format: docs/machines.md.
//
// Home coordinates: the machine coordinates of the linear axes when every axis is at 0. Every
// vector of a definition (axis directions, pivots, the spindle) is given in home coordinates, and
// each rotary axis is the line through its pivot along its direction, at home. The chain is the
// thesis's form-shaping chain (document 000, section 3.4.1) with the offsets it leaves out.
#pragma once

#include "machine/frame.hpp"
#include "machine/geometric_errors.hpp"

#include <nlohmann/json_fwd.hpp>

#include <cstddef>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

namespace cutload::machine {

// A bad machine definition: the message starts with the key path, e.g.
// "tool_side[1].direction: expected an array of 3 numbers [x, y, z]".
class MachineError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

enum class AxisType { Linear, Rotary };
// Which side of the bed an axis is on: it moves the workpiece (table) or the tool (head).
enum class Side { Workpiece, Tool };

inline constexpr std::size_t kMaxAxes = 6;   // X, Y, Z, A, B, C: each letter at most once

struct Axis {
    char name = 'X';                 // X, Y, Z (linear), A, B, C (rotary)
    AxisType type = AxisType::Linear;
    Side side = Side::Tool;
    // Unit vector, home coordinates. A positive move (sense +1) moves the tool relative to the
    // workpiece along it (linear) or turns the tool right-handed about it (rotary): ISO 841, the
    // same whether the axis moves the table or the head.
    Eigen::Vector3d direction = Eigen::Vector3d::UnitX();
    Eigen::Vector3d pivot_mm = Eigen::Vector3d::Zero();   // rotary: a point on the axis line at home
    int sense = 1;                   // -1: the logged value turns (moves) the other way
    // Travel, in the logged unit (mm or deg); infinite: unlimited (a continuous C table).
    double lower = -std::numeric_limits<double>::infinity();
    double upper = std::numeric_limits<double>::infinity();
    std::string channel;             // log channel the position is read from ("a"), case-insensitive
    AxisErrors errors;

    bool rotary() const { return type == AxisType::Rotary; }
};

struct Spindle {
    Eigen::Vector3d gauge_point_mm = Eigen::Vector3d::Zero();  // at home
    Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();           // unit, from the tip toward the spindle
    Eigen::Vector3d x_direction = Eigen::Vector3d::UnitX();    // unit, normal to axis: the tool frame's x at home
};

enum class MachineKind { ThreeAxis, FourAxisTable, FourAxisHead, TableTable, HeadTable, HeadHead };
const char* kind_name(MachineKind kind);   // "table-table", ...

struct Machine {
    std::string name;
    std::vector<Axis> chain;         // from the workpiece to the tool: the workpiece side, then the tool side
    Spindle spindle;

    MachineKind kind() const;
    bool has_errors() const;
    // Position of the axis named `name` in the chain; throws MachineError if there is none.
    std::size_t index_of(char name) const;
};

// Explicit form ({"workpiece_side": [...], "tool_side": [...]}) or form-shaping code form
// ({"code": "C A b Y X Z t", "axes": {...}}); see docs/machines.md. Throws MachineError naming the key.
Machine parse_machine(const nlohmann::json& j);
// As parse_machine; errors are prefixed with the file name, or with `shown_as` when given (a
// service names the part a client uploaded, not the path it stored it at).
Machine load_machine(const std::string& path, const std::string& shown_as = "");
// Replaces the errors of the machine's axes by those of an "errors" object (the same schema as a
// definition's "errors" key); `path` prefixes the key paths of error messages.
void set_errors(Machine& machine, const nlohmann::json& errors, const std::string& path = "errors");
// set_errors from a file holding such an object (data/machines/ac_table_table_errors.json);
// messages name the file as load_machine's do.
void load_errors(Machine& machine, const std::string& path, const std::string& shown_as = "");

// Form-shaping code (document 000, eq. 3.25, and Inasaki's letter notation): the chain from the
// workpiece to the tool as axis letters X Y Z A B C or motion digits 1-6 (1/2/3: along X/Y/Z,
// 4/5/6: about X/Y/Z), with "b" for the bed between the table's and the head's axes, an optional
// leading "w" (workpiece) and trailing "t" (tool); spaces are ignored. "C A b Y X Z t" and
// "w64b213t" are the same machine. Returns the axes with name, type, side and nominal direction
// set; throws MachineError with `path` naming the key.
std::vector<Axis> parse_form_shaping_code(const std::string& code, const std::string& path = "code");

}  // namespace cutload::machine
