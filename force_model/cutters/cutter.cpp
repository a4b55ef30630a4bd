#include "cutters/cutter.hpp"
#include "cutters/shapes.hpp"

namespace cutload::force_model {

namespace {

// The shape decides the corner radius of flat and ball tools whatever the spec's field says (the
// run spec parser only requires the field to agree).
double corner_radius_mm(const ToolSpec& tool) {
    switch (tool.shape) {
        case ToolShape::Flat: return 0;
        case ToolShape::Ball: return tool.diameter_mm / 2;
        case ToolShape::Bull: return tool.corner_radius_mm;
        case ToolShape::Drill:
        case ToolShape::Chamfer:
        case ToolShape::Barrel: return 0;
    }
    return tool.corner_radius_mm;
}

CutterProfile profile_from_spec(const ToolSpec& tool) {
    switch (tool.shape) {
        case ToolShape::Drill: return cone_profile(tool.diameter_mm, 0, tool.point_angle_deg, tool.flute_length_mm);
        case ToolShape::Chamfer:
            return cone_profile(tool.diameter_mm, tool.tip_diameter_mm, tool.point_angle_deg, tool.flute_length_mm);
        case ToolShape::Barrel:
            return barrel_profile(tool.diameter_mm, tool.barrel_radius_mm, tool.tip_radius_mm, tool.flute_length_mm);
        default:
            return tapered_end_mill_profile(tool.diameter_mm, corner_radius_mm(tool), tool.taper_deg, tool.flute_length_mm);
    }
}

}  // namespace

Cutter cutter_from_spec(const ToolSpec& tool) {
    return Cutter{profile_from_spec(tool), tool.flutes, tool.helix_deg, tool.stickout_mm, tool.holder.diameter_mm,
                  tool.holder.length_mm};
}

}  // namespace cutload::force_model
