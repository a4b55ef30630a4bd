// Internal: a cutter as the engine takes it: the profile of its cutting edges, the flutes along
// them, and the holder above. Built from the run spec's tool by cutter_from_spec, the one place
// that reads ToolShape; tests build other shapes directly (cutters/shapes.hpp).
#pragma once

#include "force_model/force_model.hpp"
#include "cutters/profile.hpp"

namespace cutload::force_model {

struct Cutter {
    CutterProfile profile;
    int flutes = 2;
    // Helix angle on the cylinder; elsewhere the flutes keep its lead (cutters/tool_geometry.hpp).
    double helix_deg = 30;
    double stickout_mm = 30;          // tip to holder face: the lever arm of the bending moment
    double holder_diameter_mm = 0;    // 0: no holder beyond the shank
    double holder_length_mm = 0;
};

Cutter cutter_from_spec(const ToolSpec& tool);

}  // namespace cutload::force_model
