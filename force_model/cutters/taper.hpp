// Internal: the one formula for a tapered end mill's flank, header-only so that the run spec
// parser (which checks the diameter where the flutes end) and the profile builder share it without
// the parser linking the cutters.
#pragma once

#include <cmath>
#include <numbers>

namespace cutload::force_model {

// Radius of a tapered flank at height z_mm above the tip. The tool: tip diameter diameter_mm (twice
// the corner arc's centre radius plus the corner radius), corner radius corner_radius_mm, flank at
// taper_deg to the axis. The corner arc ends where its normal is the flank's, at height
// rc (1 - sin(beta)) and radius R - rc + rc cos(beta); above it the radius grows by tan(beta) per mm.
inline double tapered_flank_radius_mm(double diameter_mm, double corner_radius_mm, double taper_deg, double z_mm) {
    const double R = diameter_mm / 2, rc = corner_radius_mm, beta = taper_deg * std::numbers::pi / 180;
    const double r_end = R - rc + rc * std::cos(beta), z_end = rc * (1 - std::sin(beta));
    return r_end + (z_mm - z_end) * std::tan(beta);
}

}  // namespace cutload::force_model
