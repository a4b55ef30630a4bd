// Barrel tools (document 003, Suzuki and Morishige): a tip ball on the axis and a flank arc of a
// much larger radius whose centre lies across the axis, so that a tilted tool cuts with a nearly
// flat edge and leaves a small cusp at a large step-over. The figure is missing from the source
// text; the geometry (docs/five_axis.md §5.2) is the one reading that makes the parameters
// consistent: the arc touches the ball from inside and ends at its widest point, where its normal
// is horizontal, so a cylinder of the widest radius can continue it up to the end of the flutes.
#include "cutters/barrel.hpp"
#include "cutters/shapes.hpp"
#include "force_model/force_model.hpp"

#include <cmath>
#include <numbers>
#include <stdexcept>

namespace cutload::force_model {

CutterProfile barrel_profile(double diameter_mm, double barrel_radius_mm, double tip_radius_mm, double flute_length_mm) {
    const double r = diameter_mm / 2, r1 = barrel_radius_mm, r2 = tip_radius_mm;
    if (!(r > 0 && r2 > 0 && r2 < r && r1 > r))
        throw std::invalid_argument("barrel tool: needs 0 < tip radius < diameter / 2 < barrel radius");
    const double z_b = barrel_widest_height_mm(diameter_mm, r1, r2);
    if (!(flute_length_mm >= z_b - 1e-9))
        throw std::invalid_argument("barrel tool: the flutes must reach the barrel's widest point");
    // The joint's normal: along the line from the arc's centre (r - r1, z_b) through the ball's
    // centre (0, r2), at kappa from the downward axis with sin(kappa) = (r1 - r) / (r1 - r2).
    const double kappa_joint = std::asin((r1 - r) / (r1 - r2));
    std::vector<ProfileSegment> segments{ArcSegment{0, r2, r2, 0, kappa_joint},
                                         ArcSegment{r - r1, z_b, r1, kappa_joint, std::numbers::pi / 2}};
    if (flute_length_mm - z_b > 1e-9) segments.push_back(LineSegment{{r, z_b}, {r, flute_length_mm}});
    return CutterProfile(std::move(segments));
}

double pick_feed_mm(double arc_radius_mm, double cusp_height_mm) {
    const double rho = arc_radius_mm, h = cusp_height_mm;
    if (!(rho > 0 && h > 0 && h <= rho))
        throw std::invalid_argument("pick feed: needs an arc radius > 0 and a cusp height in (0, arc radius]");
    // Two circles of radius rho, s apart, cross h below their tops: (s / 2)^2 + (rho - h)^2 = rho^2.
    return 2 * std::sqrt(h * (2 * rho - h));
}

}  // namespace cutload::force_model
