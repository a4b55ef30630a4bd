// Cone tips (drills, spot drills, chamfer mills) and tapered flanks: a straight flank at half the
// point angle to the axis.
#include "cutters/shapes.hpp"

#include <cmath>
#include <numbers>
#include <stdexcept>

namespace cutload::force_model {

CutterProfile cone_profile(double diameter_mm, double tip_diameter_mm, double point_angle_deg, double flute_length_mm) {
    const double R = diameter_mm / 2, r_tip = tip_diameter_mm / 2;
    if (!(R > 0) || !(r_tip >= 0) || !(r_tip < R))
        throw std::invalid_argument("cone cutter: need diameter > 0 and 0 <= tip diameter < diameter");
    if (!(point_angle_deg > 0 && point_angle_deg < 180))
        throw std::invalid_argument("cone cutter: the point angle must be in (0, 180) degrees");
    const double half_angle_rad = point_angle_deg / 2 * std::numbers::pi / 180;   // flank to axis
    const double cone_height_mm = (R - r_tip) / std::tan(half_angle_rad);
    if (!(flute_length_mm >= cone_height_mm - 1e-9))
        throw std::invalid_argument("cone cutter: the cone reaches the diameter " + std::to_string(cone_height_mm) +
                                    " mm above the tip, beyond the flute length");
    std::vector<ProfileSegment> segments;
    if (r_tip > 1e-9) segments.push_back(LineSegment{{0, 0}, {r_tip, 0}});
    segments.push_back(LineSegment{{r_tip, 0}, {R, cone_height_mm}});
    if (flute_length_mm - cone_height_mm > 1e-9) segments.push_back(LineSegment{{R, cone_height_mm}, {R, flute_length_mm}});
    return CutterProfile(std::move(segments));
}

}  // namespace cutload::force_model
