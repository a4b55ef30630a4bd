// The multi-direction (tri-dexel) stock for tools at any orientation, and its removal by a convex
// tool solid swept along chords (docs/five_axis.md, section 3). Scalar reference code: the layout
// is the one an OpenCL kernel will read (one work item per ray), so this is the twin-to-be.
//
// Why three families: a Z-map holds one height field, exact along Z and a cell coarse across it; a
// tilted tool leaves walls and undercuts that a height field cannot hold. Three families of
// parallel rays (along X, Y and Z) over the same box describe one solid; each is exact along its
// own rays, so a wall normal to X is exact on the X rays, and an overhang shows on X and Y rays
// as material above air.
#pragma once

#include "kernels/engine_kernels.hpp"

#include <array>
#include <cstddef>
#include <limits>
#include <vector>

namespace cutload::kernels {

// Rays along axis `axis` (0 x, 1 y, 2 z) on the grid over the two other axes, in cyclic order:
// u = (axis + 1) % 3, v = (axis + 2) % 3. Ray (i, j) is the line u = u0 + (i + 0.5) g,
// v = v0 + (j + 0.5) g; its intervals are positions along `axis`, kDexelFloats floats per ray as
// in the Z-map (lo[4], hi[4], sorted, unused slots empty), row-major (j * nu + i), unencoded. The
// counts are the box's size in whole cells, rounded as make_stock rounds them, so the Z family
// (u = x, v = y) lies exactly as a Z-map of the same box.
struct RayFamily {
    int axis = 2;
    double u0_mm = 0, v0_mm = 0;
    int nu = 0, nv = 0;
    std::vector<float> rays;
    std::size_t count() const { return std::size_t(nu) * std::size_t(nv); }
    float* ray(std::size_t r) { return rays.data() + r * kDexelFloats; }
    const float* ray(std::size_t r) const { return rays.data() + r * kDexelFloats; }
};

struct TriDexel {
    double cell_mm = 0.1;
    std::array<double, 3> lo_mm{}, hi_mm{};   // the box the families cover
    std::array<RayFamily, 3> family;          // index = axis

    std::size_t bytes() const;
    // Material volume as family f sees it (its rays' lengths times the cell area).
    double volume_mm3(int f) const;
};

// Bytes a box of this size takes at cell_mm, for the memory limit before anything is allocated.
std::size_t tri_dexel_bytes(const std::array<double, 3>& lo_mm, const std::array<double, 3>& hi_mm, double cell_mm);
// A full box of material. Throws std::invalid_argument for an empty box or a cell that is not > 0.
TriDexel make_tri_dexel_box(const std::array<double, 3>& lo_mm, const std::array<double, 3>& hi_mm, double cell_mm);

// The tool's cutting part as a convex solid of revolution, in the tool frame (origin at the tip,
// +z along the axis toward the spindle): z_lo <= z <= z_hi and, for every cone, rho <= a + b z with
// rho the distance from the axis. A concave radius profile r(z) (flat, ball, bull, cone tip, barrel,
// a taper widening upward) is the intersection of its pieces' extended cones; on [z_lo, z_hi] each
// extension lies outside the profile, so a + b z >= 0 there and each constraint is one nappe. It is
// also the union of its pieces, each its own cone over its own heights [z0, z1], which is how
// line_in_solid meets it.
struct ConvexToolSolid {
    double z_lo_mm = 0, z_hi_mm = 20;
    std::vector<std::array<double, 4>> cones;   // {a_mm, b, z0_mm, z1_mm}, from the tip up
    double radius_mm = 4;                       // the largest radius: bounds the solid
};

// Builds the solid from a polyline r(z) from the tip up (points with rising z; a first horizontal
// piece at z = 0 is the flat bottom). Throws std::invalid_argument when r(z) is not concave (a neck
// or a step), since the solid would not be convex.
ConvexToolSolid convex_tool_solid(const std::vector<std::array<double, 2>>& r_z_mm);

// The part of the line p + t u (tool frame, u need not be unit) inside the solid: [t_in, t_out];
// false when they do not meet.
bool line_in_solid(const ConvexToolSolid& solid, const std::array<double, 3>& p, const std::array<double, 3>& u,
                   double& t_in, double& t_out);

// A chord of the tool's motion: the tip moves from `from_mm` to `to_mm` (stock frame) while the tool
// keeps the orientation `rot` (columns: the tool's x, y, z axes in stock coordinates).
struct ToolChord {
    std::array<double, 3> from_mm{}, to_mm{};
    std::array<std::array<double, 3>, 3> rot{};   // rot[row][col]
};

// The part of the stock-frame line p + t u (u unit) inside the solid swept along the chord:
// [t_in, t_out], the union over the sweep of the solid's intervals (one interval, since the sweep
// of a convex solid along a segment is convex). `samples` positions along the chord find the
// stretch where the line meets the solid, then golden-section search refines the ends (the entry
// is convex and the exit concave along the chord).
// `ray`, when given, is the material along the line (positions t, a family's ray with p at its 0):
// an end is then refined only where the ray holds material beyond the sampled end, since elsewhere
// refining it cannot change what subtracting [t_in, t_out] removes.
bool line_in_sweep(const ConvexToolSolid& solid, const ToolChord& chord, const std::array<double, 3>& p,
                   const std::array<double, 3>& u, int samples, double& t_in, double& t_out, const float* ray = nullptr);

// Where a chord's sweep can reach: a box around it (the solid lies in the cylinder of its largest
// radius about the axis, at both ends of the chord) and the samples along the chord that
// line_in_sweep takes there. The OpenCL removal gets these from the host, so both use this.
struct ChordReach {
    std::array<double, 3> lo_mm{}, hi_mm{};
    int samples = 2;
};
ChordReach chord_reach(const ConvexToolSolid& solid, const ToolChord& chord, double cell_mm);
// The rays of family f a reach can touch: [i0, i1] x [j0, j1] on its grid (empty when i1 < i0 or
// j1 < j0).
struct RayRect {
    int i0 = 0, i1 = -1, j0 = 0, j1 = -1;
};
RayRect rays_in_reach(const TriDexel& stock, int f, const ChordReach& reach);

// Removes the sweep of the solid along each chord from all three families, in order. Returns the
// material removed as each family measures it (mm^3; the three agree to the discretisation).
std::array<double, 3> sweep_tri_dexel(TriDexel& stock, const ConvexToolSolid& solid, const ToolChord* chords,
                                      std::size_t n_chords);

// Whether the stock-frame point lies in material on family f's ray nearest it (outside the box:
// no). `boundary_mm`, when given, receives the distance along that ray to its nearest interval end
// (infinity when the ray holds nothing or the point is off the family's grid).
bool tri_dexel_contains(const TriDexel& stock, int f, const std::array<double, 3>& p_mm, double* boundary_mm = nullptr);
// Whether the point is in material, as told by the family whose ray has a boundary nearest the
// point along it. Each family is exact along its rays and a cell coarse across them; a surface
// near the point is crossed most directly (its boundary lies nearest) by the family most nearly
// along its normal, which is the one that places it exactly. Away from every surface the families
// agree.
bool tri_dexel_inside(const TriDexel& stock, const std::array<double, 3>& p_mm);
// The family whose rays are most nearly along the direction n (largest |n_f|).
int best_family(const std::array<double, 3>& n);

// ---- Shank and holder against the stock, for any orientation (docs/five_axis.md section 6) ----------
// The tool's body above its flutes, in the tool frame: the shank rho <= shank_radius_mm for z in
// [flute_length_mm, stickout_mm], the holder rho <= holder_radius_mm for z in [stickout_mm,
// stickout_mm + holder_length_mm] (its face at the stickout).
struct ToolBody {
    double flute_length_mm = 20, stickout_mm = 30, holder_length_mm = 40;
    double shank_radius_mm = 4, holder_radius_mm = 16;
};
// What one check found. contact: material inside the shank or the holder (document 004's (5)).
// clearance_mm: without contact, the distance from the holder to the nearest material within the
// clearance shell (document 004's V_sh, (6)); infinity where none is that near, or with contact.
struct BodyClearance {
    bool contact = false;
    double clearance_mm = std::numeric_limits<double>::infinity();
};
// One ray's material against the body: the ray is the tool-frame line p + t u, t its positions
// (the family's coordinate), `ray` its intervals. Contact needs an overlap above a micrometre at the
// flutes' top and the holder's face, and the shank is taken 2 % narrower, so material the flutes
// have just cut to their length or radius does not read as contact (as the Z-map engine's check).
// The clearance is the exact distance from the holder's cylinder to the material's nearest point
// on the ray, which is convex along it (golden section between the ends of the part in the shell).
BodyClearance ray_body_clearance(const float* ray, const std::array<double, 3>& p, const std::array<double, 3>& u,
                                 const ToolBody& body, double shell_mm);
// The box around the shank and the holder grown by the shell at a pose, cut to the stock's box
// (false: they do not meet). The OpenCL check gets it from the host, so both use this.
bool body_reach(const TriDexel& stock, const std::array<double, 3>& tip_mm,
                const std::array<std::array<double, 3>, 3>& rot, const ToolBody& body, double shell_mm,
                ChordReach& box);
// Every ray of the three families that can reach the shank or the holder grown by the shell, at
// the tool's pose (tip, rot: columns the tool's axes in stock coordinates). shell_mm 0: contact only.
BodyClearance tri_dexel_body_clearance(const TriDexel& stock, const std::array<double, 3>& tip_mm,
                                       const std::array<std::array<double, 3>, 3>& rot, const ToolBody& body,
                                       double shell_mm);

// ---- Engagement for any orientation (docs/five_axis.md section 4) ---------------------------------
// One engine step: the tool's pose in the stock frame and its motion per tooth in its own frame
// (the twist of eqs. 3.16-3.22 times the tooth period), so an edge point r feeds by
// feed + turn x r per tooth, and its uncut chip is that feed along its normal.
struct PoseStep {
    std::array<double, 3> tip_mm{};
    std::array<std::array<double, 3>, 3> rot{};   // columns: the tool's x, y, z axes in stock coordinates
    std::array<double, 3> feed_mm{};              // the tip's feed per tooth, tool frame
    std::array<double, 3> turn_rad{};             // the tool's rotation per tooth (omega), tool frame
    double theta_rad = 0;                         // spindle angle
};

// The scalar engagement of engage_twin on the tri-dexel stock, for any orientation. Edge elements,
// spindle angle, helix lag, the cutting law and the moments are as in engage_twin, in the tool
// frame; forces and moments are turned into the stock frame for StepResult (fx, fy, fz; mx, my
// are the tool-frame bending moments about the holder face, about the tool's x and y). An axial
// element cuts with the fraction of its span inside material on the ray of the family most nearly
// along the tool axis (exact along the axis, as the Z-map's), where a sub-cell inside test (the
// signed distance along each family's four rays around the point, blended; tri_dexel_inside where
// no family's four rays see one surface) agrees that its engaged part is material; a flat-bottom
// element where the point is inside, its chip limited to the material behind it along its normal.
void engage_tri_dexel(const PoseStep* steps, std::size_t n, double spin, const EdgeTable& tool, const EngageParams& p,
                      const TriDexel& stock, StepResult* out);

}  // namespace cutload::kernels
