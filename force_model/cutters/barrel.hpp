// Internal: the one formula for where a barrel tool's flank arc sits, header-only so that the run
// spec parser (which checks the flute length against it) and the profile builder share it without
// the parser linking the cutters.
#pragma once

#include <cmath>

namespace cutload::force_model {

// Height above the tip of a barrel tool's widest point, which is also the height of its flank
// arc's centre (document 003; docs/five_axis.md §5.2). The tool: widest diameter diameter_mm (2 r),
// flank arc of radius barrel_radius_mm (r1) centred across the axis at r - r1, tip ball of
// radius tip_radius_mm (r2) centred on the axis at height r2. The arc touches the ball from inside,
// so the centres are r1 - r2 apart: z_b = r2 + sqrt((r1 - r2)^2 - (r1 - r)^2), written as
// (r - r2)(2 r1 - r - r2) under the root so that a very large r1 loses no digits.
// Requires 0 < r2 < r < r1; NaN otherwise.
inline double barrel_widest_height_mm(double diameter_mm, double barrel_radius_mm, double tip_radius_mm) {
    const double r = diameter_mm / 2, r1 = barrel_radius_mm, r2 = tip_radius_mm;
    if (!(r2 > 0 && r2 < r && r < r1)) return std::nan("");
    return r2 + std::sqrt((r - r2) * (2 * r1 - r - r2));
}

}  // namespace cutload::force_model
