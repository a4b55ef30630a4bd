// Flat, ball and bull-nose end mills: the family with a corner radius (Altintas' general end mill
// with no tapers).
#include "cutters/shapes.hpp"

#include <numbers>
#include <stdexcept>

namespace cutload::force_model {

CutterProfile corner_radius_profile(double diameter_mm, double corner_radius_mm, double flute_length_mm) {
    const double R = diameter_mm / 2, rc = corner_radius_mm;
    if (!(R > 0) || !(rc >= 0) || rc > R + 1e-9 || !(flute_length_mm >= rc))
        throw std::invalid_argument("end mill: the diameter must be > 0, the corner radius in [0, diameter / 2] "
                                    "and the flute length at least the corner radius");
    std::vector<ProfileSegment> segments;
    const double a = R - rc;   // radius where the flat bottom meets the corner arc
    if (a > 1e-9) segments.push_back(LineSegment{{0, 0}, {a, 0}});
    if (rc > 1e-9) segments.push_back(ArcSegment{a, rc, rc, 0, std::numbers::pi / 2});
    if (flute_length_mm - rc > 1e-9) segments.push_back(LineSegment{{R, rc}, {R, flute_length_mm}});
    return CutterProfile(std::move(segments));
}

}  // namespace cutload::force_model
