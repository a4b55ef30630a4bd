// NC programs under tool-centre-point control (G43.4/G43.5; docs/five_axis.md section 2.4, 
// docs/nc_program.md "Tool-centre-point programs") turned into machine-axis form: straight pieces
// along which every machine axis moves linearly, as a program written in A/B/C words is read. So
// everything downstream of the reader (the commanded path, block mapping, the generator) takes a
// tool-centre-point program as it takes a machine-axis one.
//
// Why here: the reader (motion_io) must not know machine definitions, and machine/ knows no
// programs; the application has both. The reader gets the kinematics through
// motion_io::ToolCentrePointKinematics, and this header keeps Eigen out (the front ends include it).
#pragma once

#include "motion_io/nc_program.hpp"

#include <cstddef>
#include <memory>

namespace cutload::machine {
struct Machine;   // machine/machine.hpp
}

namespace cutload::app {

// The machine's kinematics on its nominal chain, as a controller in tool-centre-point mode uses
// them (machine::forward and machine::inverse: the solution nearest the previous axes within the
// limits); for NcReadOptions::tool_centre_point and machine_axis_program. `tool_length_mm`: gauge
// point to tip.
std::shared_ptr<const motion_io::ToolCentrePointKinematics> tool_centre_point_kinematics(
    std::shared_ptr<const machine::Machine> machine, double tool_length_mm);

// How closely joint-space interpolation between the pieces follows the tool-centre-point path:
// the tip within 1 um of its straight line (docs/five_axis.md section 2.4), and the tool axis within
// 1e-5 rad of its interpolated direction (1 um at 100 mm up the tool; for G43.4 the axis is exact,
// its rotary angles being linear in both). The most pieces one block and the whole program become.
inline constexpr double kTcpTipTolMm = 1e-3;
inline constexpr double kTcpAxisTolRad = 1e-5;
struct TcpPieceLimits {
    std::size_t per_block = std::size_t(1) << 16;
    std::size_t total = std::size_t(1) << 20;   // blocks of the result, pieces or not
};

// True when a block of the program is under tool-centre-point control.
bool has_tool_centre_point(const motion_io::NcProgram& program);

// The program with each moving tool-centre-point block replaced by pieces in machine-axis form
// sharing its name and line (NcBlock::tcp Off; start/end_mm and start/end_deg the machine's axes).
// The tip moves linearly at its feed, so piece k of a block takes the share of the block's time
// its stretch of the tip path (or of the turn, for a block that only turns the tool) is. Points
// along the block: tip linear; G43.4 rotary angles linear, the linear axes solved for the tip;
// G43.5 the tool axis along the great circle, every axis from the inverse kinematics nearest the
// point before. Bisected until the joint-space midpoint of every piece lies within kTcpTipTolMm
// and kTcpAxisTolRad of the path. Other blocks are copied. Throws motion_io::NcProgramError naming
// file, line and block when a point is out of reach (the axis and its limits), when a block needs
// more than `limits` pieces, or when the axes along the block end on another solution than the
// reader found for its end.
motion_io::NcProgram machine_axis_program(const motion_io::NcProgram& program,
                                          const motion_io::ToolCentrePointKinematics& kinematics,
                                          const TcpPieceLimits& limits = {});

}  // namespace cutload::app
