// Internal: a cutter as a profile in the (r, z) half-plane, the envelope of its cutting edges turned
// about the tool axis: r is the distance from the axis, z the height above the tip. The profile is a
// chain of segments from the tip (on the axis, z = 0) up to the end of the flutes. Straight segments
// make flat bottoms, cylinders, cones and tapers; arcs make corner radii, ball noses and barrel
// flanks. Everything the engine needs from a tool shape (edge elements for the engagement kernel,
// the lower surface for removal) is derived from the profile, so a new shape is a new profile
// builder (cutters/shapes.hpp) and nothing else (docs/architecture.md, "Where to change what").
#pragma once

#include <variant>
#include <vector>

namespace cutload::force_model {

struct ProfilePoint {
    double r_mm = 0, z_mm = 0;
};

// A straight piece from `from` to `to`.
struct LineSegment {
    ProfilePoint from, to;
};

// A circular arc about (centre_r_mm, centre_z_mm). The position on the arc is the angle kappa of the
// outward surface normal, measured from the downward axis (-z) towards +r: kappa 0 is the arc's
// lowest point, pi/2 its point farthest from the axis. The arc runs from from_rad to to_rad
// (increasing). A barrel flank is an arc whose centre lies across the axis (centre_r_mm < 0).
struct ArcSegment {
    double centre_r_mm = 0, centre_z_mm = 0, radius_mm = 0;
    double from_rad = 0, to_rad = 0;
    ProfilePoint at(double kappa_rad) const;
};

using ProfileSegment = std::variant<LineSegment, ArcSegment>;

ProfilePoint segment_start(const ProfileSegment& s);
ProfilePoint segment_end(const ProfileSegment& s);
double segment_length_mm(const ProfileSegment& s);

class CutterProfile {
public:
    // Throws std::invalid_argument saying which segment breaks a rule: the chain starts at the tip
    // (r = 0, z = 0), each segment starts where the one before ends, r never negative, and z never
    // falls along the chain (the engine's edge elements are sorted by height).
    explicit CutterProfile(std::vector<ProfileSegment> segments);

    const std::vector<ProfileSegment>& segments() const { return segments_; }
    double radius_mm() const { return radius_mm_; }   // largest radius: the cutting radius
    double length_mm() const { return length_mm_; }   // height of the last point: the flute length
    // Lowest point of the cutter at distance r_mm from the axis, as height above the tip; r_mm is
    // clamped to [0, radius_mm()]. This is the surface a sweep leaves behind.
    double lower_surface_mm(double r_mm) const;

private:
    std::vector<ProfileSegment> segments_;
    double radius_mm_ = 0, length_mm_ = 0;
};

// The profile as a polyline through points on it from the tip up, each arc divided so that no
// chord strays more than sagitta_mm from it (inscribed: the polyline lies on or inside the
// profile). The multi-direction stock cuts with the solid this polyline turns about the axis
// (kernels/tri_dexel.hpp), a stack of cones that one quadratic serves, instead of tori.
std::vector<ProfilePoint> profile_polyline(const CutterProfile& profile, double sagitta_mm);

}  // namespace cutload::force_model
