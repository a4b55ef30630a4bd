// Flat, ball and bull-nose end mills, cylindrical or tapered: the family with a corner radius
// (Altintas' general end mill with its taper on the flank; no taper on the bottom).
#include "cutters/shapes.hpp"

#include <cmath>
#include <numbers>
#include <stdexcept>

namespace cutload::force_model {

namespace {

double to_rad(double deg) { return deg * std::numbers::pi / 180; }

}  // namespace

CutterProfile corner_radius_profile(double diameter_mm, double corner_radius_mm, double flute_length_mm) {
    return tapered_end_mill_profile(diameter_mm, corner_radius_mm, 0, flute_length_mm);
}

CutterProfile tapered_end_mill_profile(double diameter_mm, double corner_radius_mm, double taper_deg,
                                       double flute_length_mm) {
    const double R = diameter_mm / 2, rc = corner_radius_mm;
    if (!(R > 0) || !(rc >= 0) || rc > R + 1e-9 || !(flute_length_mm >= rc))
        throw std::invalid_argument("end mill: the diameter must be > 0, the corner radius in [0, diameter / 2] "
                                    "and the flute length at least the corner radius");
    if (!(taper_deg >= 0 && taper_deg < 45))
        throw std::invalid_argument("end mill: the taper must be in [0, 45) degrees per side");
    const double beta = to_rad(taper_deg);
    std::vector<ProfileSegment> segments;
    const double a = R - rc;   // radius where the flat bottom meets the corner arc
    if (a > 1e-9) segments.push_back(LineSegment{{0, 0}, {a, 0}});
    // The arc's normal turns from straight down (kappa 0) to the flank's, pi/2 - beta.
    const ArcSegment corner{a, rc, rc, 0, std::numbers::pi / 2 - beta};
    if (rc > 1e-9) segments.push_back(corner);
    // Untapered, the cylinder starts at exactly (R, rc) and rises straight; tapered, the flank
    // starts where the arc ends (the flat's edge without a corner).
    const ProfilePoint flank_from = taper_deg == 0 ? ProfilePoint{R, rc}
                                    : rc > 1e-9    ? corner.at(corner.to_rad)
                                                   : ProfilePoint{R, 0};
    if (flute_length_mm - flank_from.z_mm > 1e-9) {
        const double top_r_mm = taper_deg == 0 ? R : tapered_flank_radius_mm(diameter_mm, rc, taper_deg, flute_length_mm);
        segments.push_back(LineSegment{flank_from, {top_r_mm, flute_length_mm}});
    }
    return CutterProfile(std::move(segments));
}

}  // namespace cutload::force_model
