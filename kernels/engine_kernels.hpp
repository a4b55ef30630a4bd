// The two heavy loops of the force engine, as data layouts shared by the OpenCL kernels
// (engage.cl, remove.cl) and their scalar C++ twins (twins.cpp).
//
// The twins are the reference: double precision, trigonometry evaluated per edge element. The
// kernels do the same arithmetic in float with precomputed per-element rotations, so the two paths
// agree to float rounding (tests require 0.5 % on forces).
#pragma once

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace cutload::kernels {

// ---- Dexel (multi-interval Z-map) grid -----------------------------------------------------------
// Cell (i, j) is the vertical ray at x = x0 + (i + 0.5) g, y = y0 + (j + 0.5) g. Each ray holds up to
// kDexelIntervals material intervals [lo, hi), as lo[4] then hi[4] (8 floats per cell), sorted by
// lo; unused slots are empty ([kEmptyLo, kEmptyHi)), so "inside" needs no count. In memory the rays
// are encoded (RayCodec below).
constexpr int kDexelIntervals = 4;
constexpr int kDexelFloats = 2 * kDexelIntervals;
constexpr float kEmptyLo = 1e30f;
constexpr float kEmptyHi = -1e30f;
// Material thinner than this is numerical dust from float round-off and repeated sweeps: removal
// drops such leftovers and engagement ignores overlaps this short.
constexpr double kSliverMm = 1e-4;

struct GridInfo {
    double x0_mm = 0, y0_mm = 0, cell_mm = 0.1;
    int nx = 0, ny = 0;
};

using Ray = std::array<float, kDexelFloats>;
constexpr Ray kNoMaterial{kEmptyLo, kEmptyLo, kEmptyLo, kEmptyLo, kEmptyHi, kEmptyHi, kEmptyHi, kEmptyHi};

// Rays are stored with each float's bits XOR-ed with a base column (the stock box's full column),
// so a ray that was never cut is all zero bytes: a fresh stock needs no fill, and its memory can
// come straight from zeroed OS pages that are only faulted in where the tool cuts.
struct RayCodec {
    std::array<std::uint32_t, kDexelFloats> base{};
    static RayCodec for_column(float z_lo_mm, float z_hi_mm);
    Ray decode(const float* stored) const;
    void encode(const Ray& ray, float* stored) const;
    float base_top() const;
};

// ---- Sub-cell walls -------------------------------------------------------------------------------
// A ray samples the material at its cell centre only, so a side wall left by a sweep is known to
// within a cell: an edge point near the wall may sit in a cell whose centre stayed outside the swept
// volume although the point itself is inside it (a re-cut of a finished wall would "cut" there),
// or the other way round. So each ray whose centre lies within a band of a sweep's side wall also
// keeps that wall (the nearest one): the plane tangent to the tool's cylinder at the closest
// approach, as the signed clearance of the centre beyond it (negative: the centre was swept), its
// unit normal (pointing away from the path, into the material) and the height from which the
// cylinder stands (tip + lower surface at R). Engagement uses it to place an edge point
// against the wall to well within a cell (docs/force_model.md, "Sub-cell walls").
//
// A second wall per ray keeps the side surface lower down: of the walls recorded, the one that
// starts lowest (z_from; within a cell of height, the smaller clearance). A higher sweep that takes
// the centre in deeper (a ring above, a retract) decides the first slot, and without the second the
// lower sweep's wall would be lost below the higher one's z_from. The second slot is empty when it
// would hold the first slot's wall. Engagement uses it only to take out the material on its swept
// side (docs/force_model.md, "Sub-cell walls").
//
// Stored as kWallSlots walls of 4 floats per ray (the deepest, then the lowest), the clearance's
// bits XOR-ed with kNoWall's, so all-zero bytes mean "no wall recorded" (lazily mapped pages, like
// the rays). A ray with a wall says so itself: its
// last interval slot holds [kWallMark, kEmptyHi), an empty interval to every reader, so engagement
// fetches a wall only for the rays that have one (a gather per edge point into a second array cost
// the kernel a third of its speed). A ray whose four slots all hold material carries no mark, and
// its wall is not used.
constexpr float kNoWall = 1e30f;
constexpr float kWallMark = 2e30f;
constexpr int kWallFloats = 4;
constexpr int kWallSlots = 2;
inline bool has_wall_mark(const float* ray) { return ray[kDexelIntervals - 1] == kWallMark; }
// Marks the ray when its last slot is free; returns whether it carries the mark.
bool set_wall_mark(float* ray);

struct Wall {
    float clearance_mm = kNoWall;   // signed horizontal distance of the cell centre beyond the wall plane
    float z_from_mm = 0;            // the wall holds for material at and above this height
    float nx = 0, ny = 0;           // unit normal of the wall plane, into the material
    bool exists() const { return clearance_mm < kNoWall; }
    bool operator==(const Wall&) const = default;
};

// Whether wall `a` displaces `b` in a ray's first slot (the smaller clearance: the sweep that takes
// the centre in deepest, else the nearest wall) and in its second slot (the lower z_from; walls
// starting within z_tolerance_mm of each other count as one height, and the smaller clearance wins).
bool deeper_wall(const Wall& a, const Wall& b);
bool lower_wall(const Wall& a, const Wall& b, float z_tolerance_mm);

Wall decode_wall(const float* stored);
void encode_wall(const Wall& w, float* stored);

// The stored dexel grid as the kernels and twins see it.
struct DexelView {
    float* cells = nullptr;   // kDexelFloats per ray, row-major (j * nx + i), encoded with codec
    float* walls = nullptr;   // kWallSlots * kWallFloats per ray, same order, encoded with encode_wall
    GridInfo grid;
    RayCodec codec;
    Ray load(std::size_t r) const { return codec.decode(cells + r * kDexelFloats); }
    void store(std::size_t r, const Ray& ray) const { codec.encode(ray, cells + r * kDexelFloats); }
    // slot 0: the deepest wall; slot 1: the lowest one, when it is another wall
    Wall wall(std::size_t r, int slot = 0) const { return decode_wall(walls + (r * kWallSlots + slot) * kWallFloats); }
    void store_wall(std::size_t r, const Wall& w, int slot = 0) const {
        encode_wall(w, walls + (r * kWallSlots + slot) * kWallFloats);
    }
};

// ---- Tool edge elements --------------------------------------------------------------------------
// One element per piece of the tool profile in the (r, z) half-plane, for one flute; sorted by z so a
// batch can stop at the highest element that can reach material. The first `bottom_count` elements
// have a downward normal (flat end): they can only cut while the tool descends.
struct EdgeTable {
    std::vector<double> r_mm, z_mm;          // edge point: radius, height above the tip
    std::vector<double> nr, nz;              // outward surface normal (radial, axial components)
    std::vector<double> db_mm;               // chip width (element length along the profile)
    std::vector<double> z_lo_mm, z_hi_mm;    // axial extent of the element; an element with z_hi > z_lo cuts
                                             // with the fraction of it inside material (axial weighting)
    std::vector<double> lag_rad;             // helix lag behind the flute's tip
    int flutes = 2;
    int bottom_count = 0;
    std::size_t size() const { return r_mm.size(); }
};

struct CuttingCoefficients {
    double Ktc = 0, Krc = 0, Kac = 0;   // N/mm^2
    double Kte = 0, Kre = 0, Kae = 0;   // N/mm
};

// The cutting law on one edge element (force_model/cutting_law.hpp): tangential, radial and axial
// force for a chip of thickness h over an engaged length db. engage.cl computes the same in float.
struct ElementForce {
    double tangential_N = 0, radial_N = 0, axial_N = 0;
};
inline ElementForce element_force(const CuttingCoefficients& k, double h_mm, double db_mm) {
    return {(k.Ktc * h_mm + k.Kte) * db_mm, (k.Krc * h_mm + k.Kre) * db_mm, (k.Kac * h_mm + k.Kae) * db_mm};
}

// ---- One batch of time steps ---------------------------------------------------------------------
// Spindle rotation: an edge point of flute j at element e points along
//   alpha = pi/2 - theta - 2 pi j / N + spin * lag_e      (machine XY, counter-clockwise from +X)
// so spindle angle 0 puts flute 0's tip on +Y and M03 (spin +1) turns clockwise seen from above.
// spin -1 (M04) mirrors the cutter (left-hand helix, cutting counter-clockwise).
struct StepBatch {
    std::vector<double> tip_x, tip_y, tip_z;       // tool tip in stock coordinates, mm
    std::vector<double> feed_x, feed_y, feed_z;    // feed per tooth vector, mm
    std::vector<double> theta_rad;                 // spindle angle
    // cos and sin of A = pi/2 - theta (flute 0's tip direction), for the kernels; the twins take
    // the trigonometry of theta_rad per element instead, as the reference.
    std::vector<double> cos_a, sin_a;
    double spin = 1;                               // +1 M03, -1 M04, for the whole batch
    std::size_t size() const { return tip_x.size(); }
    void clear();
    void reserve(std::size_t n);
};

// Per step, summed over flutes and engaged elements. Forces act on the tool in machine axes.
struct StepResult {
    float fx_N = 0, fy_N = 0, fz_N = 0;
    float torque_Nmm = 0;                // sum of r * dFt: the load on the spindle
    float mx_Nmm = 0, my_Nmm = 0;        // bending moment about the holder face
    float chip_mm = 0;                   // max uncut chip thickness
    float q_min_mm = 0, q_max_mm = 0;    // engaged extent across the feed direction
    float z_min_mm = 0, z_max_mm = 0;    // engaged extent along the axis (above the tip)
    float engaged = 0;                   // number of engaged elements
};
static_assert(sizeof(StepResult) == 12 * sizeof(float), "StepResult mirrors the kernel's 12 floats");

// One step's sums over its engaged elements, in the tool's own frame (x, y across the axis, z up
// it): the twins' one place for how an element's cutting force becomes the step's forces, moments
// and engaged extents (engage.cl and tri_dexel.cl repeat it in their own types).
struct StepSums {
    double Fx = 0, Fy = 0, Fz = 0, T = 0, Mx = 0, My = 0, chip = 0;
    double qmin = 1e30, qmax = -1e30, zmin = 1e30, zmax = -1e30;
    int engaged = 0;

    // An element at radius r_mm and z_mm above the tip whose edge points along (cu, su), outward
    // normal (nr, nz), cutting a chip h_mm over db_mm; (px, py) is across the feed; [z_lo, z_hi]
    // its engaged part, heights above the tip.
    void add(const CuttingCoefficients& k, double spin, double h_mm, double db_mm, double r_mm, double z_mm,
             double cu, double su, double nr, double nz, double holder_face_z_mm, double px, double py,
             double z_lo_mm, double z_hi_mm) {
        const ElementForce f = element_force(k, h_mm, db_mm);
        const double dFt = f.tangential_N, dFr = f.radial_N, dFa = f.axial_N;
        const double normal = dFr * nr + dFa * nz;
        const double ex = -spin * dFt * su - normal * cu;
        const double ey = spin * dFt * cu - normal * su;
        const double ez = -dFr * nz + dFa * nr;
        Fx += ex;
        Fy += ey;
        Fz += ez;
        T += r_mm * dFt;
        const double lz = z_mm - holder_face_z_mm;
        Mx += r_mm * su * ez - lz * ey;
        My += lz * ex - r_mm * cu * ez;
        chip = std::max(chip, h_mm);
        const double q = r_mm * (cu * px + su * py);
        qmin = std::min(qmin, q);
        qmax = std::max(qmax, q);
        zmin = std::min(zmin, z_lo_mm);
        zmax = std::max(zmax, z_hi_mm);
        ++engaged;
    }

    // The result with the forces (fx, fy, fz) as given (already turned into the stock frame where
    // the tool's frame is not the stock's); the rest as summed.
    StepResult result(double fx_N, double fy_N, double fz_N) const {
        StepResult o;
        o.fx_N = float(fx_N);
        o.fy_N = float(fy_N);
        o.fz_N = float(fz_N);
        o.torque_Nmm = float(T);
        o.mx_Nmm = float(Mx);
        o.my_Nmm = float(My);
        o.chip_mm = float(chip);
        o.q_min_mm = engaged ? float(qmin) : 0.0f;
        o.q_max_mm = engaged ? float(qmax) : 0.0f;
        o.z_min_mm = engaged ? float(zmin) : 0.0f;
        o.z_max_mm = engaged ? float(zmax) : 0.0f;
        o.engaged = float(engaged);
        return o;
    }
};

struct EngageParams {
    CuttingCoefficients k;
    double holder_face_z_mm = 30;   // lever arm origin: height of the holder face above the tip
    double min_chip_mm = 0;         // an element cuts only where h exceeds this (minimum chip thickness)
    // An edge point counts as past a recorded wall (in material) only when it is deeper than this.
    double wall_tolerance_mm = kSliverMm;
    int element_end = 0;            // elements [0, element_end) may reach material in this batch
    // OpenCL: an edge point over a ray whose top (refresh_tops_twin) is not above the element is not
    // looked up. The weights are the same either way; the twin looks up every point.
    bool skip_lookups_below_tops = true;
};

// ---- Swept-volume removal ------------------------------------------------------------------------
// The tool's cutting part moving along straight segments of the tip path. Its lower surface is the
// profile's lower envelope, tabulated as height above the tip at radius d = i * lower_dr_mm.
struct SweepSegment {
    double ax, ay, az, bx, by, bz;
};

struct SweepParams {
    std::vector<double> lower_mm;   // lower surface height over radius, lower_mm.size() >= 2
    double radius_mm = 4;           // cutting radius (last table entry)
    double cut_length_mm = 20;      // flute length: material above it is not cut (shank contact)
    double wall_band_mm = 0.1;      // walls are recorded for rays whose centre clears the tool by less
};

// One removal call: segments [first_segment, first_segment + segments) of a shared list, applied to
// the rays of a cell rectangle. Calls run in order; each writes width * height results.
struct SweepCall {
    std::size_t first_segment = 0, segments = 0;
    int i0 = 0, j0 = 0, width = 0, height = 0;
    std::size_t cells() const { return std::size_t(width) * std::size_t(height); }
};

struct SweepCellResult {
    float removed_mm = 0;   // material length removed from the ray
    float top_mm = 0;       // new top of the ray (kEmptyHi when empty)
};

// Scalar twins.
void engage_twin(const StepBatch& steps, const EdgeTable& tool, const EngageParams& p, const DexelView& stock,
                 StepResult* out);
void sweep_twin(const SweepSegment* segs, const SweepCall& call, const SweepParams& p, const DexelView& stock,
                SweepCellResult* out);

// Shared interval arithmetic (also used to build and check stocks): removes [a, b) from one ray;
// returns the length removed. When the ray would need more than kDexelIntervals pieces, the
// narrowest gap is filled (material kept: the conservative choice for collision checks).
double subtract_interval(float* ray, double a_mm, double b_mm);
double ray_length(const float* ray);
float ray_top(const float* ray);
bool ray_contains(const float* ray, double z_mm);
inline double ray_length(const Ray& ray) { return ray_length(ray.data()); }
inline float ray_top(const Ray& ray) { return ray_top(ray.data()); }
// The per-ray tops by which engage.cl skips the lookups that cannot find material (nothing an edge
// point may read from a ray reaches above its top), for the rays [i0, i1) x [j0, j1): a ray's top,
// or for a ray with the wall mark the highest top of it and its eight neighbours (its material may
// be the ray's one cell across its wall). Stored as the bits of the top XOR-ed with those of
// stock.codec.base_top(), so a ray never cut is 0; written only where the value changes. Twin of
// remove.cl's refresh_tops; the OpenCL backend keeps the tops of its stock beside it.
void refresh_tops_twin(const DexelView& stock, int i0, int j0, int i1, int j1, std::uint32_t* tops);
// Length of [a, b) inside the ray's material (pieces over kSliverMm), and the lowest and highest
// material point in it.
double ray_overlap(const float* ray, double a_mm, double b_mm, double& lo_mm, double& hi_mm);

// Height of the tabulated lower surface at radius d (linear interpolation).
double lower_surface(const SweepParams& p, double d_mm);

}  // namespace cutload::kernels
