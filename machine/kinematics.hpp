// Forward and inverse kinematics of a machine definition (machine/machine.hpp).
//
// Forward: axis positions -> the tool frame in workpiece coordinates, the product of the chain's
// stages from the workpiece to the tool (document 000, eq. 3.28), each stage optionally preceded by
// its axis's geometric errors (section 3.4.2). Inverse: a tool tip and axis in workpiece
// coordinates -> axis positions of the nominal chain, nearest a previous position within limits
// (what a controller does for a tool-centre-point program, G43.4 style).
//
// Workpiece coordinates are fixed to the table and coincide with home coordinates when every axis
// is at 0. A work offset (where the part's zero sits) is a further constant translation, applied
// by whoever owns the setup (the run spec), not here.
#pragma once

#include "machine/frame.hpp"
#include "machine/machine.hpp"

#include <array>
#include <map>
#include <stdexcept>
#include <string>

namespace cutload::machine {

// Positions in chain order, in the logged units (mm for linear axes, deg for rotary ones).
struct AxisPositions {
    std::array<double, kMaxAxes> value{};
};

// Builds positions from axis letters; an axis left out is at 0. Throws MachineError for a letter
// the machine does not have.
AxisPositions positions(const Machine& m, const std::map<char, double>& by_name);

enum class ErrorMode { Nominal, WithErrors };

// The tool frame: origin at the tool tip, z along the tool axis toward the spindle (document 000,
// section 3.2: +z up the shank), x the spindle's x_direction carried by the head. The spindle's own
// rotation is not part of it.
struct ToolPose {
    Frame tool_to_workpiece;

    const Eigen::Vector3d& tip_mm() const { return tool_to_workpiece.origin_mm; }
    Eigen::Vector3d axis() const { return tool_to_workpiece.R.col(2); }
};

// tool_length_mm: gauge point to tip along the spindle axis.
ToolPose forward(const Machine& m, const AxisPositions& q, double tool_length_mm,
                 ErrorMode mode = ErrorMode::WithErrors);

// The bed (machine) frame in workpiece coordinates: the product of the workpiece-side stages. Its
// rotation turns a vector in machine axes into workpiece axes (forces on the tool are reported in
// both).
Frame bed_to_workpiece(const Machine& m, const AxisPositions& q, ErrorMode mode = ErrorMode::WithErrors);

// Both of the above from one walk of the chain: the workpiece-side stages lead the chain, so the
// bed frame is forward()'s product part way along. For a caller that needs both at every step (the
// machine-axis forces of each prediction row): one walk instead of a full and a half one. Equal,
// bit for bit, to forward() and bed_to_workpiece() (the same products in the same order).
struct ToolAndBed {
    ToolPose tool;
    Frame bed_to_workpiece;
};
ToolAndBed forward_with_bed(const Machine& m, const AxisPositions& q, double tool_length_mm,
                            ErrorMode mode = ErrorMode::WithErrors);

// A target the nominal chain cannot reach (orientation impossible for its rotary axes, or outside
// the limits). The message says which axis and by how much.
class KinematicsError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

// Axis positions that put the tool tip at tip_mm with its axis along `axis` (unit, toward the
// spindle) in workpiece coordinates, on the nominal chain. Of the solutions within limits, the one
// nearest `previous` (rotary angles taken modulo 360 deg to the nearest equivalent): least sum of
// squared rotary differences in deg. Where an angle is undetermined (the tool axis on a rotary axis
// line: a vertical tool on a C table), it keeps its previous value. Supports exactly three linear
// axes with independent directions and up to two rotary axes.
AxisPositions inverse(const Machine& m, const Eigen::Vector3d& tip_mm, const Eigen::Vector3d& axis,
                      double tool_length_mm, const AxisPositions& previous);

}  // namespace cutload::machine
