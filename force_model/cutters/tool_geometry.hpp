// Internal: a cutter turned into the tables the kernels and their scalar twins read: edge elements
// for engagement, the lower surface for swept-volume removal, and the holder's size for the
// contact checks. Built once per prediction; any profile works, so the engine never asks which
// shape it holds.
#pragma once

#include "cutters/cutter.hpp"
#include "kernels/engine_kernels.hpp"

#include <vector>

namespace cutload::force_model {

struct ToolGeometry {
    kernels::EdgeTable edges;
    std::vector<double> lower_mm;   // lower surface height above the tip, evenly over radius [0, radius_mm]
    double radius_mm = 4;           // cutting radius: the profile's largest
    double flute_length_mm = 20;    // material above this is shank contact, not cut
    double stickout_mm = 30;
    double holder_radius_mm = 16, holder_length_mm = 40;
    double shank_diameter_mm = 8;   // for the bending stress: taken equal to the cutting diameter
    double holder_clearance_mm = 0; // the near-miss shell around the holder (Limits); 0: none

    // The elements that can reach material rising to height_mm above the tip: [0, result). The
    // elements are sorted by height, so a batch stops at the highest material under it.
    int elements_reaching(double height_mm) const;
};

// Edge elements of about axial_step_mm along the profile (arc length on arcs), the element at the
// middle of each piece. Helix lag: constant lead, psi = z tan(helix) / R with R the cutting radius,
// which is Altintas' 2 z tan(beta) / D on the cylinder, zero on a flat bottom (straight end teeth)
// and the usual constant-lead helix on corner arcs and cones.
ToolGeometry build_tool_geometry(const Cutter& cutter, double axial_step_mm);

}  // namespace cutload::force_model
