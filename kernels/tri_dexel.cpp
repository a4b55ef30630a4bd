#include "tri_dexel.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>

namespace cutload::kernels {

namespace {

using Vec = std::array<double, 3>;
constexpr double kInf = std::numeric_limits<double>::infinity();

// Whole cells, rounded as the Z-map's make_stock rounds them (a box that is a multiple of the cell
// is exact), so the Z family and a Z-map of the same box are laid out alike.
int axis_count(double lo, double hi, double cell) { return std::max(1, int(std::lround((hi - lo) / cell))); }

Vec sub(const Vec& a, const Vec& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }

// rot^T v: stock-frame vector into the tool frame.
Vec to_tool(const std::array<Vec, 3>& rot, const Vec& v) {
    return {rot[0][0] * v[0] + rot[1][0] * v[1] + rot[2][0] * v[2], rot[0][1] * v[0] + rot[1][1] * v[1] + rot[2][1] * v[2],
            rot[0][2] * v[0] + rot[1][2] * v[1] + rot[2][2] * v[2]};
}

// Minimum of f on [a, b] by golden-section search, where f is convex on the stretch it is finite
// on and +inf beyond, and `anchor` in [a, b] is known finite: on a tie of two infinite probes the
// finite stretch lies on the anchor's side.
template <class F>
double golden_min(F&& f, double a, double b, double anchor, double best, int iterations) {
    constexpr double kPhi = 0.6180339887498949;
    double x1 = b - kPhi * (b - a), x2 = a + kPhi * (b - a);
    double f1 = f(x1), f2 = f(x2);
    for (int k = 0; k < iterations; ++k) {
        const bool keep_left = f1 < f2 || (f1 == f2 && anchor <= x1);
        if (keep_left) {
            b = x2;
            x2 = x1;
            f2 = f1;
            x1 = b - kPhi * (b - a);
            f1 = f(x1);
        } else {
            a = x1;
            x1 = x2;
            f1 = f2;
            x2 = a + kPhi * (b - a);
            f2 = f(x2);
        }
        best = std::min({best, f1, f2});
    }
    return std::min({best, f1, f2});
}

}  // namespace

std::size_t tri_dexel_bytes(const std::array<double, 3>& lo_mm, const std::array<double, 3>& hi_mm, double cell_mm) {
    std::size_t rays = 0;
    for (int f = 0; f < 3; ++f) {
        const int u = (f + 1) % 3, v = (f + 2) % 3;
        rays += std::size_t(axis_count(lo_mm[u], hi_mm[u], cell_mm)) * std::size_t(axis_count(lo_mm[v], hi_mm[v], cell_mm));
    }
    return rays * kDexelFloats * sizeof(float);
}

TriDexel make_tri_dexel_box(const std::array<double, 3>& lo_mm, const std::array<double, 3>& hi_mm, double cell_mm) {
    if (!(cell_mm > 0) || !std::isfinite(cell_mm))
        throw std::invalid_argument("tri-dexel stock: the cell size must be > 0 mm, got " + std::to_string(cell_mm));
    for (int a = 0; a < 3; ++a)
        if (!(hi_mm[a] > lo_mm[a]))
            throw std::invalid_argument("tri-dexel stock: the box is empty along axis " + std::string(1, "xyz"[a]));
    TriDexel s;
    s.cell_mm = cell_mm;
    s.lo_mm = lo_mm;
    s.hi_mm = hi_mm;
    for (int f = 0; f < 3; ++f) {
        RayFamily& fam = s.family[f];
        const int u = (f + 1) % 3, v = (f + 2) % 3;
        fam.axis = f;
        fam.u0_mm = lo_mm[u];
        fam.v0_mm = lo_mm[v];
        fam.nu = axis_count(lo_mm[u], hi_mm[u], cell_mm);
        fam.nv = axis_count(lo_mm[v], hi_mm[v], cell_mm);
        fam.rays.assign(fam.count() * kDexelFloats, 0.0f);
        for (int j = 0; j < fam.nv; ++j)
            for (int i = 0; i < fam.nu; ++i) {
                float* ray = fam.ray(std::size_t(j) * fam.nu + i);
                std::copy(kNoMaterial.begin(), kNoMaterial.end(), ray);
                ray[0] = float(lo_mm[f]);
                ray[kDexelIntervals] = float(hi_mm[f]);
            }
    }
    return s;
}

std::size_t TriDexel::bytes() const {
    std::size_t b = 0;
    for (const RayFamily& f : family) b += f.rays.size() * sizeof(float);
    return b;
}

double TriDexel::volume_mm3(int f) const {
    const RayFamily& fam = family[f];
    double len = 0;
    for (std::size_t r = 0; r < fam.count(); ++r) len += ray_length(fam.ray(r));
    return len * cell_mm * cell_mm;
}

ConvexToolSolid convex_tool_solid(const std::vector<std::array<double, 2>>& r_z_mm) {
    if (r_z_mm.size() < 2) throw std::invalid_argument("tool solid: the profile needs at least two points");
    ConvexToolSolid s;
    s.z_lo_mm = r_z_mm.front()[1];
    s.z_hi_mm = r_z_mm.back()[1];
    s.radius_mm = 0;
    double last_slope = kInf;   // dr/dz of the piece before: concave r(z) means it never rises
    for (std::size_t k = 0; k + 1 < r_z_mm.size(); ++k) {
        const auto [r0, z0] = r_z_mm[k];
        const auto [r1, z1] = r_z_mm[k + 1];
        s.radius_mm = std::max({s.radius_mm, r0, r1});
        if (r0 < 0 || r1 < 0) throw std::invalid_argument("tool solid: a profile radius is negative");
        const double dz = z1 - z0;
        if (dz <= 1e-12) {
            // Only the flat bottom may be horizontal: the slab's lower face closes it.
            if (k == 0 && z0 == s.z_lo_mm && r0 == 0 && r1 >= 0) continue;
            throw std::invalid_argument("tool solid: profile point " + std::to_string(k + 1) +
                                        " does not rise above the one before (only the flat bottom may be horizontal)");
        }
        const double b = (r1 - r0) / dz;
        if (b > last_slope + 1e-9 * std::abs(last_slope) + 1e-12)
            throw std::invalid_argument("tool solid: the profile widens faster above point " + std::to_string(k) +
                                        " than below it (a neck or a step): the solid is not convex");
        last_slope = b;
        s.cones.push_back({r0 - b * z0, b, z0, z1});
    }
    if (s.cones.empty()) throw std::invalid_argument("tool solid: the profile has no flank");
    return s;
}

namespace {

// Narrows [lo, hi] to where the line p + t u lies inside the cone rho <= a + b z, given that
// a + b z >= 0 on the stretch; false when nothing is left.
bool clip_to_cone(double a, double b, const Vec& p, const Vec& u, double uxy, double& lo, double& hi) {
    // rho^2 - (a + b z)^2 <= 0 along the line: A t^2 + B t + C <= 0. Within the piece's slab
    // a + b z >= 0, so the other nappe (where it is negative) never enters.
    const double w0 = a + b * p[2], w1 = b * u[2];
    const double A = uxy - w1 * w1;
    const double B = 2 * (p[0] * u[0] + p[1] * u[1] - w0 * w1);
    const double C = p[0] * p[0] + p[1] * p[1] - w0 * w0;
    if (std::abs(A) <= 1e-12 * (uxy + w1 * w1)) {
        // The line runs along the cone's surface direction: one linear bound.
        if (std::abs(B) < 1e-300) return C <= 0;
        if (B > 0)
            hi = std::min(hi, -C / B);
        else
            lo = std::max(lo, -C / B);
    } else {
        const double disc = B * B - 4 * A * C;
        // A > 0: inside between the roots. A < 0: inside outside them, two half-lines, of which only
        // one meets the slab's nappe; with no real root the whole line is inside the double cone.
        if (disc < 0) return A < 0 && lo <= hi;
        const double q = -0.5 * (B + std::copysign(std::sqrt(disc), B));
        const double ra = q / A, rb = q != 0 ? C / q : ra;
        const double r1 = std::min(ra, rb), r2 = std::max(ra, rb);
        if (A > 0) {
            lo = std::max(lo, r1);
            hi = std::min(hi, r2);
        } else {
            const double left = std::min(hi, r1) - lo, right = hi - std::max(lo, r2);
            if (left < 0 && right < 0) return false;
            if (left >= right)
                hi = std::min(hi, r1);
            else
                lo = std::max(lo, r2);
        }
    }
    return lo <= hi;
}

}  // namespace

bool line_in_solid(const ConvexToolSolid& solid, const Vec& p, const Vec& u, double& t_in, double& t_out) {
    // The solid is the union of its pieces, each its own cone within its own slab of heights (on a
    // piece's slab every other extended cone lies outside it), so a line meets only the cones of
    // the slabs it crosses: one or two for a line across the axis, all of them only for a line
    // along it (a slab test costs far less than a cone's quadratic).
    const double uxy = u[0] * u[0] + u[1] * u[1];
    double lo = kInf, hi = -kInf;
    for (const auto& [a, b, z0, z1] : solid.cones) {
        double plo = -kInf, phi = kInf;
        if (std::abs(u[2]) < 1e-15) {
            if (p[2] < z0 || p[2] > z1) continue;
        } else {
            const double ta = (z0 - p[2]) / u[2], tb = (z1 - p[2]) / u[2];
            plo = std::min(ta, tb);
            phi = std::max(ta, tb);
        }
        if (!clip_to_cone(a, b, p, u, uxy, plo, phi)) continue;
        lo = std::min(lo, plo);
        hi = std::max(hi, phi);
    }
    if (!(lo <= hi && std::isfinite(lo) && std::isfinite(hi))) return false;
    t_in = lo;
    t_out = hi;
    return true;
}

bool line_in_sweep(const ConvexToolSolid& solid, const ToolChord& chord, const Vec& p, const Vec& u, int samples,
                   double& t_in, double& t_out, const float* ray) {
    const Vec p0 = to_tool(chord.rot, sub(p, chord.from_mm));
    const Vec ut = to_tool(chord.rot, u);
    const Vec d = to_tool(chord.rot, sub(chord.to_mm, chord.from_mm));
    auto at = [&](double s, double& a, double& b) {
        return line_in_solid(solid, {p0[0] - s * d[0], p0[1] - s * d[1], p0[2] - s * d[2]}, ut, a, b);
    };
    samples = std::max(samples, 2);
    const double step = 1.0 / (samples - 1);
    int k_in = -1, k_out = -1;
    double best_in = kInf, best_out = -kInf;
    for (int k = 0; k < samples; ++k) {
        double a, b;
        if (!at(k * step, a, b)) continue;
        if (a < best_in) best_in = a, k_in = k;
        if (b > best_out) best_out = b, k_out = k;
    }
    if (k_in < 0) return false;
    const int iterations = 24;
    auto entry = [&](double s) {
        double a, b;
        return at(s, a, b) ? a : kInf;
    };
    auto exit_neg = [&](double s) {
        double a, b;
        return at(s, a, b) ? -b : kInf;
    };
    const double s_in = k_in * step, s_out = k_out * step;
    // Refining an end moves it outward, into the ray's material only where there is some beyond
    // the sampled end; elsewhere what is removed is the same without it. (An unrefined interval the
    // sliver gate drops holds under kSliverMm of material, since beyond its unrefined ends there is
    // none: dust either way, and refining every such grazing ray cost 40 % of a turning run.)
    bool refine_in = true, refine_out = true;
    if (ray) {
        refine_in = refine_out = false;
        for (int k = 0; k < kDexelIntervals; ++k)
            if (ray[kDexelIntervals + k] > ray[k]) {
                refine_in = refine_in || ray[k] < best_in;
                refine_out = refine_out || ray[kDexelIntervals + k] > best_out;
            }
    }
    t_in = refine_in ? golden_min(entry, std::max(0.0, s_in - step), std::min(1.0, s_in + step), s_in, best_in, iterations)
                     : best_in;
    t_out = refine_out ? -golden_min(exit_neg, std::max(0.0, s_out - step), std::min(1.0, s_out + step), s_out, -best_out,
                                     iterations)
                       : best_out;
    return true;
}

ChordReach chord_reach(const ConvexToolSolid& solid, const ToolChord& chord, double cell_mm) {
    const double g = cell_mm;
    const Vec axis{chord.rot[0][2], chord.rot[1][2], chord.rot[2][2]};
    ChordReach r;
    r.lo_mm = {kInf, kInf, kInf};
    r.hi_mm = {-kInf, -kInf, -kInf};
    for (const Vec& o : {chord.from_mm, chord.to_mm})
        for (double z : {solid.z_lo_mm, solid.z_hi_mm})
            for (int a = 0; a < 3; ++a) {
                const double centre = o[a] + z * axis[a];
                const double reach = solid.radius_mm * std::sqrt(std::max(0.0, 1 - axis[a] * axis[a])) + 1e-9;
                r.lo_mm[a] = std::min(r.lo_mm[a], centre - reach);
                r.hi_mm[a] = std::max(r.hi_mm[a], centre + reach);
            }
    // Samples along the chord: close enough that a ray crossing the sweep's flank catches the solid
    // at one of them wherever it would take more than a twentieth of a cell off it.
    const Vec d = sub(chord.to_mm, chord.from_mm);
    const double chord_mm = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    const double spacing_mm = std::max(g, 2 * std::sqrt(2 * std::max(solid.radius_mm, g) * g / 20));
    r.samples = std::min(4096, 2 + int(std::ceil(chord_mm / spacing_mm)));
    return r;
}

RayRect rays_in_reach(const TriDexel& stock, int f, const ChordReach& reach) {
    const RayFamily& fam = stock.family[f];
    const double g = stock.cell_mm;
    const int u = (f + 1) % 3, v = (f + 2) % 3;
    // Every ray whose line can meet the box; the kernel repeats these expressions per chord.
    return {std::max(0, int(std::floor((reach.lo_mm[u] - fam.u0_mm) / g - 0.5))),
            std::min(fam.nu - 1, int(std::ceil((reach.hi_mm[u] - fam.u0_mm) / g - 0.5))),
            std::max(0, int(std::floor((reach.lo_mm[v] - fam.v0_mm) / g - 0.5))),
            std::min(fam.nv - 1, int(std::ceil((reach.hi_mm[v] - fam.v0_mm) / g - 0.5)))};
}

std::array<double, 3> sweep_tri_dexel(TriDexel& stock, const ConvexToolSolid& solid, const ToolChord* chords,
                                      std::size_t n_chords) {
    std::array<double, 3> removed{};
    const double g = stock.cell_mm;
    for (std::size_t c = 0; c < n_chords; ++c) {
        const ToolChord& chord = chords[c];
        const ChordReach reach = chord_reach(solid, chord, g);
        const Vec& lo = reach.lo_mm;
        const Vec& hi = reach.hi_mm;
        const int samples = reach.samples;
        for (int f = 0; f < 3; ++f) {
            RayFamily& fam = stock.family[f];
            const int u = (f + 1) % 3, v = (f + 2) % 3;
            const auto [i0, i1, j0, j1] = rays_in_reach(stock, f, reach);
            Vec dir{0, 0, 0};
            dir[f] = 1;
            for (int j = j0; j <= j1; ++j)
                for (int i = i0; i <= i1; ++i) {
                    float* ray = fam.ray(std::size_t(j) * fam.nu + i);
                    double m_lo, m_hi;
                    if (!(ray_overlap(ray, lo[f], hi[f], m_lo, m_hi) > 0)) continue;   // no material in reach
                    Vec p{0, 0, 0};
                    p[u] = fam.u0_mm + (i + 0.5) * g;
                    p[v] = fam.v0_mm + (j + 0.5) * g;
                    double t0, t1;
                    if (!line_in_sweep(solid, chord, p, dir, samples, t0, t1, ray)) continue;
                    if (t1 - t0 > kSliverMm) removed[f] += subtract_interval(ray, t0, t1);
                }
        }
    }
    for (double& r : removed) r *= g * g;
    return removed;
}

bool tri_dexel_contains(const TriDexel& stock, int f, const Vec& p_mm, double* boundary_mm) {
    const RayFamily& fam = stock.family[f];
    const int u = (f + 1) % 3, v = (f + 2) % 3;
    const double fu = (p_mm[u] - fam.u0_mm) / stock.cell_mm, fv = (p_mm[v] - fam.v0_mm) / stock.cell_mm;
    if (boundary_mm) *boundary_mm = kInf;
    if (!(fu >= 0 && fv >= 0 && fu < fam.nu && fv < fam.nv)) return false;
    const float* ray = fam.ray(std::size_t(fv) * fam.nu + std::size_t(fu));
    if (boundary_mm)
        for (int k = 0; k < kDexelIntervals; ++k)
            if (ray[kDexelIntervals + k] > ray[k])
                *boundary_mm = std::min({*boundary_mm, std::abs(p_mm[f] - ray[k]),
                                         std::abs(p_mm[f] - ray[kDexelIntervals + k])});
    return ray_contains(ray, p_mm[f]);
}

bool tri_dexel_inside(const TriDexel& stock, const Vec& p_mm) {
    bool inside = false;
    double nearest = kInf;
    for (int f = 0; f < 3; ++f) {
        double boundary = kInf;
        const bool in = tri_dexel_contains(stock, f, p_mm, &boundary);
        if (f == 0 || boundary < nearest) {
            nearest = boundary;
            inside = in;
        }
    }
    return inside;
}

int best_family(const Vec& n) {
    int best = 2;
    for (int f = 0; f < 3; ++f)
        if (std::abs(n[f]) > std::abs(n[best])) best = f;
    return best;
}

namespace {

Vec turn(const std::array<Vec, 3>& rot, const Vec& v) {
    return {rot[0][0] * v[0] + rot[0][1] * v[1] + rot[0][2] * v[2], rot[1][0] * v[0] + rot[1][1] * v[1] + rot[1][2] * v[2],
            rot[2][0] * v[0] + rot[2][1] * v[1] + rot[2][2] * v[2]};
}

const float* nearest_ray(const TriDexel& stock, int f, const Vec& p_mm) {
    const RayFamily& fam = stock.family[f];
    const int u = (f + 1) % 3, v = (f + 2) % 3;
    const double fu = (p_mm[u] - fam.u0_mm) / stock.cell_mm, fv = (p_mm[v] - fam.v0_mm) / stock.cell_mm;
    if (!(fu >= 0 && fv >= 0 && fu < fam.nu && fv < fam.nv)) return nullptr;
    return fam.ray(std::size_t(fv) * fam.nu + std::size_t(fu));
}

// Signed distance along the ray from x_mm to the ray's nearest interval end: positive in material,
// negative outside; -inf for a ray that holds nothing.
double ray_signed_mm(const float* ray, double x_mm) {
    double d = kInf;
    for (int k = 0; k < kDexelIntervals; ++k)
        if (ray[kDexelIntervals + k] > ray[k])
            d = std::min({d, std::abs(x_mm - ray[k]), std::abs(x_mm - ray[kDexelIntervals + k])});
    return ray_contains(ray, x_mm) ? d : -d;
}

// Whether the point is in material, placed to a fraction of a cell. A family's ray places a surface
// exactly only where it crosses it, and up to half a cell times the surface's slope across the ray
// away from there (at 0.05 mm cells tri_dexel_inside took the rounded corner's 12 mm leftover wall
// for the other side over a band 9 um wide on average; this test, 1.4 um, all of it the stock the
// removal's chords leave on the arc). Between the four rays of a family around the point a
// smooth surface is linear to within g^2 / 8 rho (rho its radius of curvature: 0.03 um for a 12 mm
// wall at 0.05 mm), and so is the signed distance along the rays to it: its bilinear blend at the
// point gives the side. A family blends only where all four of its rays have a boundary within two
// cells (they see one surface, not an edge or a surface's end); of those that do, the one with the
// least blended distance tells, as the family most nearly along the surface's normal (for a plane
// the distance along a ray is the distance to it over the normal's component along the ray). The
// nearest ray's boundary does not pick that family: across a steep wall a family's rays step by
// several cells, and one of them can end near the point by chance. Where no family blends, as
// tri_dexel_inside.
bool inside_sub_cell(const TriDexel& stock, const Vec& p_mm) {
    const double g = stock.cell_mm, reach_mm = 2 * g;
    double best_mm = kInf;
    bool inside = false;
    for (int f = 0; f < 3; ++f) {
        const RayFamily& fam = stock.family[f];
        const int u = (f + 1) % 3, v = (f + 2) % 3;
        // Ray (i, j) lies at i + 0.5 cells: the four around the point are i0, i0 + 1 and j0, j0 + 1.
        const double fu = (p_mm[u] - fam.u0_mm) / g - 0.5, fv = (p_mm[v] - fam.v0_mm) / g - 0.5;
        const double i0 = std::floor(fu), j0 = std::floor(fv);
        if (!(i0 >= 0 && j0 >= 0 && i0 + 1 < fam.nu && j0 + 1 < fam.nv)) continue;
        const std::size_t r00 = std::size_t(j0) * fam.nu + std::size_t(i0);
        const double x = p_mm[f];
        const double s00 = ray_signed_mm(fam.ray(r00), x);
        if (!(std::abs(s00) < reach_mm)) continue;
        const double s10 = ray_signed_mm(fam.ray(r00 + 1), x);
        if (!(std::abs(s10) < reach_mm)) continue;
        const double s01 = ray_signed_mm(fam.ray(r00 + fam.nu), x);
        if (!(std::abs(s01) < reach_mm)) continue;
        const double s11 = ray_signed_mm(fam.ray(r00 + fam.nu + 1), x);
        if (!(std::abs(s11) < reach_mm)) continue;
        const double wu = fu - i0, wv = fv - j0;
        const double s = (1 - wv) * ((1 - wu) * s00 + wu * s10) + wv * ((1 - wu) * s01 + wu * s11);
        if (std::abs(s) < best_mm) {
            best_mm = std::abs(s);
            inside = s > 0;
        }
    }
    return best_mm < kInf ? inside : tri_dexel_inside(stock, p_mm);
}

}  // namespace

void engage_tri_dexel(const PoseStep* steps, std::size_t n, double spin, const EdgeTable& tool, const EngageParams& p,
                      const TriDexel& stock, StepResult* out) {
    const double pitch = 2 * std::numbers::pi / tool.flutes;
    const CuttingCoefficients& k = p.k;
    for (std::size_t i = 0; i < n; ++i) {
        const PoseStep& st = steps[i];
        const Vec axis{st.rot[0][2], st.rot[1][2], st.rot[2][2]};
        const int f_axis = best_family(axis);
        const double s = spin;
        const double fxy = std::hypot(st.feed_mm[0], st.feed_mm[1]);
        const double px = fxy > 1e-12 ? -st.feed_mm[1] / fxy : 1.0, py = fxy > 1e-12 ? st.feed_mm[0] / fxy : 0.0;
        StepSums sums;
        for (int j = 0; j < tool.flutes; ++j) {
            for (int e = 0; e < p.element_end; ++e) {
                const double alpha = std::numbers::pi / 2 - st.theta_rad - j * pitch + s * tool.lag_rad[e];
                const double cu = std::cos(alpha), su = std::sin(alpha);
                const double nr = tool.nr[e], nz = tool.nz[e], r = tool.r_mm[e];
                const Vec r_tool{r * cu, r * su, tool.z_mm[e]};
                const Vec& w = st.turn_rad;
                const Vec feed{st.feed_mm[0] + w[1] * r_tool[2] - w[2] * r_tool[1],
                               st.feed_mm[1] + w[2] * r_tool[0] - w[0] * r_tool[2],
                               st.feed_mm[2] + w[0] * r_tool[1] - w[1] * r_tool[0]};
                const double h = nr * (feed[0] * cu + feed[1] * su) + nz * feed[2];
                if (h <= p.min_chip_mm) continue;
                auto at_height = [&](double z_mm) {
                    const Vec q = turn(st.rot, {r_tool[0], r_tool[1], z_mm});
                    return Vec{st.tip_mm[0] + q[0], st.tip_mm[1] + q[1], st.tip_mm[2] + q[2]};
                };
                const Vec P = at_height(tool.z_mm[e]);
                const double span = tool.z_hi_mm[e] - tool.z_lo_mm[e];
                double weight = 0, h_cut = h, clip_lo = tool.z_mm[e], clip_hi = tool.z_mm[e];
                if (span > 0) {
                    const Vec a = at_height(tool.z_lo_mm[e]), b = at_height(tool.z_hi_mm[e]);
                    const float* ray = nearest_ray(stock, f_axis, P);
                    const double lo = std::min(a[f_axis], b[f_axis]), hi = std::max(a[f_axis], b[f_axis]);
                    double m_lo = 0, m_hi = 0;
                    const double overlap = ray && hi > lo ? ray_overlap(ray, lo, hi, m_lo, m_hi) : 0;
                    if (overlap > 0) {
                        // Back to heights above the tip: the span maps onto [lo, hi] linearly.
                        const double za = tool.z_lo_mm[e], zb = tool.z_hi_mm[e];
                        const bool rising = b[f_axis] >= a[f_axis];
                        const double t_lo = (m_lo - lo) / (hi - lo), t_hi = (m_hi - lo) / (hi - lo);
                        clip_lo = rising ? za + t_lo * span : zb - t_hi * span;
                        clip_hi = rising ? za + t_hi * span : zb - t_lo * span;
                        if (inside_sub_cell(stock, at_height(0.5 * (clip_lo + clip_hi)))) weight = overlap / (hi - lo);
                    } else if (inside_sub_cell(stock, P)) {
                        // The axis family's ray, a cell across, missed a wall the point is inside of.
                        weight = 1;
                        clip_lo = tool.z_lo_mm[e];
                        clip_hi = tool.z_hi_mm[e];
                    }
                } else if (inside_sub_cell(stock, P)) {
                    // The chip is the material between this point and the previous tooth's pass, h
                    // behind it along the normal: sampled at a tenth of h (a bottom cuts thin chips).
                    const Vec nW = turn(st.rot, {nr * cu, nr * su, nz});
                    int in = 0;
                    for (int q = 1; q <= 10; ++q) {
                        const double d = -h * (q - 0.5) / 10;
                        in += inside_sub_cell(stock, {P[0] + d * nW[0], P[1] + d * nW[1], P[2] + d * nW[2]});
                    }
                    h_cut = h * in / 10;
                    if (h_cut > p.min_chip_mm) weight = 1;
                }
                if (weight <= 0) continue;
                sums.add(k, s, h_cut, tool.db_mm[e] * weight, r, tool.z_mm[e], cu, su, nr, nz, p.holder_face_z_mm, px, py,
                         clip_lo, clip_hi);
            }
        }
        const Vec F = turn(st.rot, {sums.Fx, sums.Fy, sums.Fz});
        out[i] = sums.result(F[0], F[1], F[2]);
    }
}

}  // namespace cutload::kernels
