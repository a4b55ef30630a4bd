// Internal: the chain's stages, shared by forward and inverse kinematics.
#pragma once

#include "machine/kinematics.hpp"

namespace cutload::machine::detail {

// The nominal motion of axis a at logged position q: the stage from the element on its tool side
// to the element on its workpiece side.
Frame axis_motion(const Axis& a, double q);
// The stage with the axis's geometric errors (mode WithErrors) or without.
Frame stage(const Axis& a, double q, ErrorMode mode);
// The tool frame when every axis is at 0.
Frame tool_at_home(const Spindle& s, double tool_length_mm);

}  // namespace cutload::machine::detail
