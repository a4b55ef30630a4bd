// Internal: the cutter as a profile of segments in the (r, z) half-plane (flat bottom, corner arc,
// cylinder), discretised into edge elements for the engagement kernel and into a lower-surface
// table for swept-volume removal.
#pragma once

#include "force_model/force_model.hpp"
#include "kernels/engine_kernels.hpp"

#include <vector>

namespace cutload::force_model {

struct ToolGeometry {
    kernels::EdgeTable edges;
    std::vector<double> lower_mm;   // lower surface height above the tip over radius [0, R]
    double radius_mm = 4, corner_radius_mm = 0;
    double flute_length_mm = 20, stickout_mm = 30;
    double holder_radius_mm = 16, holder_length_mm = 40;
};

// Elements of about axial_step_mm along the profile (arc length on arcs). Helix lag: constant lead,
// psi = z tan(helix) / R, which is Altintas' 2 z tan(beta) / D on the cylinder, zero on a flat
// bottom (straight end teeth) and the usual constant-lead helix on ball and bull-nose corners.
ToolGeometry build_tool_geometry(const ToolSpec& tool, double axial_step_mm);

}  // namespace cutload::force_model
