// Internal: the tool shapes, each a builder of a cutter profile from its dimensions, one file per
// shape family. Nothing else in the engine knows a shape: the edge elements, the lower surface and
// the cutting radius all come from the profile.
#pragma once

#include "cutters/profile.hpp"
#include "cutters/taper.hpp"

namespace cutload::force_model {

// end_mill.cpp: flat bottom, corner arc of radius corner_radius_mm, cylinder up to flute_length_mm.
// Corner radius 0 is a flat end mill, diameter / 2 a ball end mill, anything between a bull nose.
CutterProfile corner_radius_profile(double diameter_mm, double corner_radius_mm, double flute_length_mm);

// end_mill.cpp: the same family with a tapered flank (Altintas' general end mill with its taper):
// the corner arc ends where its normal meets the flank's, at taper_deg from the horizontal, and
// the flank rises at taper_deg to the axis up to flute_length_mm. diameter_mm is the tip's: twice
// the corner arc's centre radius plus the corner radius (a flat tool's bottom face, a ball's ball).
// taper_deg 0 is corner_radius_profile exactly.
CutterProfile tapered_end_mill_profile(double diameter_mm, double corner_radius_mm, double taper_deg,
                                       double flute_length_mm);

// cone.cpp: a cone tip with the included point angle (118 deg: a twist drill, 90 deg: a spot drill
// or chamfer mill), starting from a flat of tip_diameter_mm (0: a sharp point) and widening to
// diameter_mm, then a cylinder up to flute_length_mm. A tapered flank is the same cone with a
// small point angle (twice the taper per side) reaching diameter_mm at the end of the flutes.
CutterProfile cone_profile(double diameter_mm, double tip_diameter_mm, double point_angle_deg, double flute_length_mm);

// barrel.cpp: document 003's barrel tool: a tip ball of tip_radius_mm centred on the axis, then the
// flank arc of barrel_radius_mm (centre across the axis) from where it touches the ball up to its
// widest point, diameter_mm, at barrel_widest_height_mm (cutters/barrel.hpp); then a cylinder of
// that diameter up to flute_length_mm, which must reach the widest point.
CutterProfile barrel_profile(double diameter_mm, double barrel_radius_mm, double tip_radius_mm, double flute_length_mm);

}  // namespace cutload::force_model
