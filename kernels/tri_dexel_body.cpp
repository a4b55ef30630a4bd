// Shank and holder against the tri-dexel stock for a tool at any orientation (docs/five_axis.md
// section 6, document 004's contact (5) and clearance shell (6)).
#include "kernels/tri_dexel.hpp"

#include <algorithm>
#include <cmath>

namespace cutload::kernels {

namespace {

using Vec = std::array<double, 3>;
constexpr double kInf = std::numeric_limits<double>::infinity();
// Material must overlap the body by more than this to be contact: a wall the flutes left at their
// top or a face level with the holder's touches it without cutting into it.
constexpr double kContactOverlapMm = 1e-3;

// The part of the line p + t u inside the cylinder rho <= r, z0 <= z <= z1 (tool frame).
bool line_in_cylinder(double r_mm, double z0_mm, double z1_mm, const Vec& p, const Vec& u, double& lo, double& hi) {
    ConvexToolSolid c;
    c.z_lo_mm = z0_mm;
    c.z_hi_mm = z1_mm;
    c.cones = {{r_mm, 0.0, z0_mm, z1_mm}};
    c.radius_mm = r_mm;
    return line_in_solid(c, p, u, lo, hi);
}

// Distance from q (tool frame) to the holder's solid cylinder.
double to_holder_mm(const ToolBody& b, const Vec& q) {
    const double rho = std::hypot(q[0], q[1]);
    const double top = b.stickout_mm + b.holder_length_mm;
    const double dr = std::max(rho - b.holder_radius_mm, 0.0);
    const double dz = std::max({b.stickout_mm - q[2], q[2] - top, 0.0});
    return std::hypot(dr, dz);
}

// Whether a material interval overlaps [lo, hi] by more than the contact tolerance.
bool overlaps(const float* ray, double lo, double hi) {
    for (int k = 0; k < kDexelIntervals; ++k) {
        const double a = ray[k], b = ray[kDexelIntervals + k];
        if (b > a && std::min(b, hi) - std::max(a, lo) > kContactOverlapMm) return true;
    }
    return false;
}

}  // namespace

BodyClearance ray_body_clearance(const float* ray, const Vec& p, const Vec& u, const ToolBody& b, double shell_mm) {
    BodyClearance r;
    double lo, hi;
    // The shank from the flutes' top (the flutes cut there: material level with it is no contact).
    if (b.stickout_mm > b.flute_length_mm &&
        line_in_cylinder(b.shank_radius_mm * 0.98, b.flute_length_mm, b.stickout_mm, p, u, lo, hi) && overlaps(ray, lo, hi)) {
        r.contact = true;
        return r;
    }
    const double top = b.stickout_mm + b.holder_length_mm;
    if (line_in_cylinder(b.holder_radius_mm, b.stickout_mm, top, p, u, lo, hi) && overlaps(ray, lo, hi)) {
        r.contact = true;
        return r;
    }
    if (!(shell_mm > 0)) return r;
    // The holder grown by the shell lies inside this taller, wider cylinder; the distance is
    // measured only where a ray's material enters it.
    double g0, g1;
    if (!line_in_cylinder(b.holder_radius_mm + shell_mm, b.stickout_mm - shell_mm, top + shell_mm, p, u, g0, g1)) return r;
    const auto at = [&](double t) { return to_holder_mm(b, {p[0] + t * u[0], p[1] + t * u[1], p[2] + t * u[2]}); };
    for (int k = 0; k < kDexelIntervals; ++k) {
        const double s0 = std::max<double>(ray[k], g0), s1 = std::min<double>(ray[kDexelIntervals + k], g1);
        if (!(s1 >= s0)) continue;
        // The distance to a convex solid is convex along a line: its smallest on [s0, s1] is at an
        // end or where golden-section search closes in (0.618^60 of a 100 mm span is 3e-11 mm).
        double best = std::min(at(s0), at(s1));
        constexpr double kGolden = 0.6180339887498949;
        double a = s0, c = s1;
        double x1 = c - kGolden * (c - a), x2 = a + kGolden * (c - a);
        double f1 = at(x1), f2 = at(x2);
        for (int it = 0; it < 60 && c - a > 1e-9; ++it) {
            if (f1 <= f2) {
                c = x2, x2 = x1, f2 = f1;
                x1 = c - kGolden * (c - a);
                f1 = at(x1);
            } else {
                a = x1, x1 = x2, f1 = f2;
                x2 = a + kGolden * (c - a);
                f2 = at(x2);
            }
        }
        best = std::min({best, f1, f2});
        if (best <= shell_mm) r.clearance_mm = std::min(r.clearance_mm, best);
    }
    return r;
}

bool body_reach(const TriDexel& stock, const Vec& tip_mm, const std::array<Vec, 3>& rot, const ToolBody& b,
                double shell_mm, ChordReach& box) {
    const Vec axis{rot[0][2], rot[1][2], rot[2][2]};
    const double c = std::max(shell_mm, 0.0);
    box.lo_mm = {kInf, kInf, kInf};
    box.hi_mm = {-kInf, -kInf, -kInf};
    const double top = b.stickout_mm + b.holder_length_mm;
    for (const auto& [r_mm, z0, z1] : {std::array<double, 3>{b.shank_radius_mm, b.flute_length_mm, b.stickout_mm},
                                       std::array<double, 3>{b.holder_radius_mm + c, b.stickout_mm - c, top + c}})
        for (double z : {z0, z1})
            for (int a = 0; a < 3; ++a) {
                const double centre = tip_mm[a] + z * axis[a];
                const double reach = r_mm * std::sqrt(std::max(0.0, 1 - axis[a] * axis[a])) + 1e-9;
                box.lo_mm[a] = std::min(box.lo_mm[a], centre - reach);
                box.hi_mm[a] = std::max(box.hi_mm[a], centre + reach);
            }
    for (int a = 0; a < 3; ++a) {
        box.lo_mm[a] = std::max(box.lo_mm[a], stock.lo_mm[a]);
        box.hi_mm[a] = std::min(box.hi_mm[a], stock.hi_mm[a]);
        if (box.lo_mm[a] > box.hi_mm[a]) return false;
    }
    return true;
}

BodyClearance tri_dexel_body_clearance(const TriDexel& stock, const Vec& tip_mm, const std::array<Vec, 3>& rot,
                                       const ToolBody& b, double shell_mm) {
    BodyClearance out;
    ChordReach box;
    if (!body_reach(stock, tip_mm, rot, b, shell_mm, box)) return out;   // the body is outside the stock's box
    const double c = std::max(shell_mm, 0.0);
    const double g = stock.cell_mm;
    for (int f = 0; f < 3; ++f) {
        const RayFamily& fam = stock.family[f];
        const int u = (f + 1) % 3, v = (f + 2) % 3;
        const RayRect rect = rays_in_reach(stock, f, box);
        // The ray's direction in the tool frame: row f of rot.
        const Vec dir{rot[f][0], rot[f][1], rot[f][2]};
        for (int j = rect.j0; j <= rect.j1; ++j)
            for (int i = rect.i0; i <= rect.i1; ++i) {
                const float* ray = fam.ray(std::size_t(j) * std::size_t(fam.nu) + std::size_t(i));
                // Rays whose material stays outside the box along them cannot reach the body.
                bool near = false;
                for (int k = 0; k < kDexelIntervals && !near; ++k)
                    near = ray[kDexelIntervals + k] > ray[k] && ray[kDexelIntervals + k] >= box.lo_mm[f] &&
                           ray[k] <= box.hi_mm[f];
                if (!near) continue;
                Vec w{};
                w[f] = -tip_mm[f];
                w[u] = fam.u0_mm + (i + 0.5) * g - tip_mm[u];
                w[v] = fam.v0_mm + (j + 0.5) * g - tip_mm[v];
                // p = rot^T w: the ray's point at t = 0 in the tool frame.
                const Vec p{rot[0][0] * w[0] + rot[1][0] * w[1] + rot[2][0] * w[2],
                            rot[0][1] * w[0] + rot[1][1] * w[1] + rot[2][1] * w[2],
                            rot[0][2] * w[0] + rot[1][2] * w[1] + rot[2][2] * w[2]};
                const BodyClearance r = ray_body_clearance(ray, p, dir, b, c);
                if (r.contact) {
                    out.contact = true;
                    out.clearance_mm = kInf;
                    return out;
                }
                out.clearance_mm = std::min(out.clearance_mm, r.clearance_mm);
            }
    }
    return out;
}

}  // namespace cutload::kernels
