#include "kernels/engine_kernels.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <limits>
#include <numbers>

namespace cutload::kernels {

void StepBatch::clear() {
    for (auto* v : {&tip_x, &tip_y, &tip_z, &feed_x, &feed_y, &feed_z, &theta_rad, &cos_a, &sin_a}) v->clear();
}

void StepBatch::reserve(std::size_t n) {
    for (auto* v : {&tip_x, &tip_y, &tip_z, &feed_x, &feed_y, &feed_z, &theta_rad, &cos_a, &sin_a}) v->reserve(n);
}

RayCodec RayCodec::for_column(float z_lo_mm, float z_hi_mm) {
    RayCodec c;
    for (int k = 0; k < kDexelIntervals; ++k) {
        c.base[k] = std::bit_cast<std::uint32_t>(k == 0 ? z_lo_mm : kEmptyLo);
        c.base[kDexelIntervals + k] = std::bit_cast<std::uint32_t>(k == 0 ? z_hi_mm : kEmptyHi);
    }
    return c;
}

Ray RayCodec::decode(const float* stored) const {
    Ray r;
    for (int k = 0; k < kDexelFloats; ++k) r[k] = std::bit_cast<float>(std::bit_cast<std::uint32_t>(stored[k]) ^ base[k]);
    return r;
}

void RayCodec::encode(const Ray& ray, float* stored) const {
    for (int k = 0; k < kDexelFloats; ++k) stored[k] = std::bit_cast<float>(std::bit_cast<std::uint32_t>(ray[k]) ^ base[k]);
}

float RayCodec::base_top() const { return std::bit_cast<float>(base[kDexelIntervals]); }

Wall decode_wall(const float* stored) {
    const std::uint32_t no_wall = std::bit_cast<std::uint32_t>(kNoWall);
    return {std::bit_cast<float>(std::bit_cast<std::uint32_t>(stored[0]) ^ no_wall), stored[1], stored[2], stored[3]};
}

bool set_wall_mark(float* ray) {
    if (!(ray[kDexelIntervals - 1] == kEmptyLo || ray[kDexelIntervals - 1] == kWallMark)) return false;
    ray[kDexelIntervals - 1] = kWallMark;
    ray[2 * kDexelIntervals - 1] = kEmptyHi;
    return true;
}

void encode_wall(const Wall& w, float* stored) {
    stored[0] = std::bit_cast<float>(std::bit_cast<std::uint32_t>(w.clearance_mm) ^ std::bit_cast<std::uint32_t>(kNoWall));
    stored[1] = w.z_from_mm;
    stored[2] = w.nx;
    stored[3] = w.ny;
}

bool deeper_wall(const Wall& a, const Wall& b) { return a.clearance_mm < b.clearance_mm; }

bool lower_wall(const Wall& a, const Wall& b, float z_tolerance_mm) {
    if (!b.exists()) return a.exists();
    if (std::abs(a.z_from_mm - b.z_from_mm) > z_tolerance_mm) return a.z_from_mm < b.z_from_mm;
    return a.clearance_mm < b.clearance_mm;
}

bool ray_contains(const float* ray, double z_mm) {
    for (int k = 0; k < kDexelIntervals; ++k)
        if (z_mm >= ray[k] && z_mm < ray[kDexelIntervals + k]) return true;
    return false;
}

double ray_overlap(const float* ray, double a_mm, double b_mm, double& lo_mm, double& hi_mm) {
    double len = 0;
    lo_mm = std::numeric_limits<double>::infinity();
    hi_mm = -lo_mm;
    for (int k = 0; k < kDexelIntervals; ++k) {
        const double a = std::max(a_mm, double(ray[k])), b = std::min(b_mm, double(ray[kDexelIntervals + k]));
        if (!(b - a > kSliverMm)) continue;
        len += b - a;
        lo_mm = std::min(lo_mm, a);
        hi_mm = std::max(hi_mm, b);
    }
    return len;
}

double ray_length(const float* ray) {
    double len = 0;
    for (int k = 0; k < kDexelIntervals; ++k)
        if (ray[kDexelIntervals + k] > ray[k]) len += double(ray[kDexelIntervals + k]) - double(ray[k]);
    return len;
}

float ray_top(const float* ray) {
    float top = kEmptyHi;
    for (int k = 0; k < kDexelIntervals; ++k)
        if (ray[kDexelIntervals + k] > ray[k]) top = std::max(top, ray[kDexelIntervals + k]);
    return top;
}

void refresh_tops_twin(const DexelView& stock, int i0, int j0, int i1, int j1, std::uint32_t* tops) {
    const GridInfo& g = stock.grid;
    const std::uint32_t base = std::bit_cast<std::uint32_t>(stock.codec.base_top());
    for (int j = std::max(j0, 0); j < std::min(j1, g.ny); ++j)
        for (int i = std::max(i0, 0); i < std::min(i1, g.nx); ++i) {
            const Ray ray = stock.load(std::size_t(j) * g.nx + std::size_t(i));
            float top = ray_top(ray);
            if (has_wall_mark(ray.data()))
                for (int b = std::max(j - 1, 0); b <= std::min(j + 1, g.ny - 1); ++b)
                    for (int a = std::max(i - 1, 0); a <= std::min(i + 1, g.nx - 1); ++a)
                        top = std::max(top, ray_top(stock.load(std::size_t(b) * g.nx + std::size_t(a))));
            const std::uint32_t value = std::bit_cast<std::uint32_t>(top) ^ base;
            std::uint32_t& stored = tops[std::size_t(j) * g.nx + std::size_t(i)];
            if (stored != value) stored = value;
        }
}

double subtract_interval(float* ray, double a_mm, double b_mm) {
    std::array<std::pair<double, double>, kDexelIntervals + 1> piece{};
    int n = 0;
    const double before = ray_length(ray);
    for (int k = 0; k < kDexelIntervals; ++k) {
        const double lo = ray[k], hi = ray[kDexelIntervals + k];
        if (!(hi > lo)) continue;
        if (b_mm <= lo || a_mm >= hi) {
            piece[n++] = {lo, hi};
            continue;
        }
        if (a_mm - lo > kSliverMm) piece[n++] = {lo, a_mm};
        if (hi - b_mm > kSliverMm) piece[n++] = {b_mm, hi};
    }
    // Pieces come out ordered: the rays are sorted and a split yields its lower piece first.
    if (n > kDexelIntervals) {
        int narrowest = 0;
        for (int k = 1; k + 1 < n; ++k)
            if (piece[k + 1].first - piece[k].second < piece[narrowest + 1].first - piece[narrowest].second)
                narrowest = k;
        piece[narrowest].second = piece[narrowest + 1].second;
        std::copy(piece.begin() + narrowest + 2, piece.begin() + n, piece.begin() + narrowest + 1);
        --n;
    }
    for (int k = 0; k < kDexelIntervals; ++k) {
        ray[k] = k < n ? float(piece[k].first) : kEmptyLo;
        ray[kDexelIntervals + k] = k < n ? float(piece[k].second) : kEmptyHi;
    }
    return before - ray_length(ray);
}

double lower_surface(const SweepParams& p, double d_mm) {
    const auto last = p.lower_mm.size() - 1;
    const double u = std::clamp(d_mm / p.radius_mm, 0.0, 1.0) * double(last);
    const auto i = std::min<std::size_t>(static_cast<std::size_t>(u), last - 1);
    const double w = u - double(i);
    return p.lower_mm[i] * (1 - w) + p.lower_mm[i + 1] * w;
}

namespace {

// Where the tool passes over the ray at (cx, cy) while its tip runs along one segment: the lowest
// point of its lower surface (zb) and the highest point of its cutting part (zt). False when the
// ray stays outside the cutting radius. Either way, when the side wall at the closest approach lies
// within the band of the ray's centre, it replaces `deep` if deeper_wall and `low` if lower_wall.
bool segment_cover(const SweepSegment& s, double cx, double cy, const SweepParams& p, double& zb, double& zt,
                   Wall& deep, Wall& low) {
    const double ux = s.bx - s.ax, uy = s.by - s.ay, uz = s.bz - s.az;
    const double wx = s.ax - cx, wy = s.ay - cy;
    // horizontal distance squared along the segment: A t^2 + B t + C
    const double A = ux * ux + uy * uy, B = 2 * (ux * wx + uy * wy), C = wx * wx + wy * wy;
    const double R = p.radius_mm, R2 = R * R;
    const double tc = A < 1e-18 ? 0.0 : std::clamp(-B / (2 * A), 0.0, 1.0);   // closest approach
    const double d2 = std::max(0.0, (A * tc + B) * tc + C);
    const double d = std::sqrt(d2);
    if (std::abs(d - R) < p.wall_band_mm && d > 1e-9) {
        const Wall side{float(d - R), float(s.az + uz * tc + p.lower_mm.back()), float(-(wx + ux * tc) / d),
                        float(-(wy + uy * tc) / d)};
        if (deeper_wall(side, deep)) deep = side;
        if (lower_wall(side, low, float(p.wall_band_mm))) low = side;
    }
    if (d2 > R2) return false;
    double t0 = 0, t1 = 1;
    if (A >= 1e-18) {
        const double sq = std::sqrt(std::max(0.0, B * B - 4 * A * (C - R2)));
        t0 = std::max(0.0, (-B - sq) / (2 * A));
        t1 = std::min(1.0, (-B + sq) / (2 * A));
    }
    auto height = [&](double t) {
        const double d = std::sqrt(std::max(0.0, A * t * t + B * t + C));
        return s.az + uz * t + lower_surface(p, d);
    };
    double best;
    if (std::abs(uz) < 1e-12) {
        // Level move: the lower surface rises with radius, so the closest approach is lowest.
        best = height(tc);
    } else {
        // Ramp or plunge: height(t) is convex (convex rising profile of a convex distance plus a
        // linear term), so a golden-section search finds its minimum.
        constexpr double kInvPhi = 0.6180339887498949;
        double lo = t0, hi = t1;
        double m1 = hi - kInvPhi * (hi - lo), m2 = lo + kInvPhi * (hi - lo);
        double h1 = height(m1), h2 = height(m2);
        for (int it = 0; it < 24; ++it) {
            if (h1 < h2) {
                hi = m2; m2 = m1; h2 = h1; m1 = hi - kInvPhi * (hi - lo); h1 = height(m1);
            } else {
                lo = m1; m1 = m2; h1 = h2; m2 = lo + kInvPhi * (hi - lo); h2 = height(m2);
            }
        }
        best = std::min({h1, h2, height(t0), height(t1)});
    }
    zb = best;
    zt = std::max(s.az + uz * t0, s.az + uz * t1) + p.cut_length_mm;
    return true;
}

}  // namespace

void sweep_twin(const SweepSegment* segs, const SweepCall& call, const SweepParams& p, const DexelView& stock,
                SweepCellResult* out) {
    const GridInfo& grid = stock.grid;
    for (int jj = 0; jj < call.height; ++jj) {
        for (int ii = 0; ii < call.width; ++ii) {
            const int i = call.i0 + ii, j = call.j0 + jj;
            const std::size_t index = std::size_t(j) * grid.nx + i;
            const double cx = grid.x0_mm + (i + 0.5) * grid.cell_mm, cy = grid.y0_mm + (j + 0.5) * grid.cell_mm;
            double zb = std::numeric_limits<double>::infinity(), zt = -zb;
            Wall deep, low;   // this call's candidates; the stored ones are read only if there are any
            for (std::size_t k = 0; k < call.segments; ++k) {
                double b, t;
                if (segment_cover(segs[call.first_segment + k], cx, cy, p, b, t, deep, low)) {
                    zb = std::min(zb, b);
                    zt = std::max(zt, t);
                }
            }
            SweepCellResult& r = out[std::size_t(jj) * call.width + ii];
            const Ray before = stock.load(index);
            // The stored walls are read only for a marked ray (remove.cl says why).
            bool marked = has_wall_mark(before.data());
            if (deep.exists()) {
                const Wall had_deep = marked ? stock.wall(index, 0) : Wall{};
                const Wall had_low = marked ? stock.wall(index, 1) : Wall{};
                const Wall new_deep = deeper_wall(deep, had_deep) ? deep : had_deep;
                const Wall low_before = had_low.exists() ? had_low : had_deep;
                Wall new_low = lower_wall(low, low_before, float(p.wall_band_mm)) ? low : low_before;
                if (new_low == new_deep) new_low = Wall{};
                if (!(new_deep == had_deep)) stock.store_wall(index, new_deep, 0);
                if (!(new_low == had_low)) stock.store_wall(index, new_low, 1);
                marked = true;
            }
            Ray ray = before;
            r.removed_mm = zb < zt ? float(subtract_interval(ray.data(), zb, zt)) : 0.0f;
            if (marked) set_wall_mark(ray.data());
            // Unchanged rays are not written back: their pages stay untouched.
            if (ray != before) stock.store(index, ray);
            r.top_mm = ray_top(ray);
        }
    }
}

namespace {

// The material at the edge point (x, y) in cell (ci, cj), as a ray. The cell's ray describes its
// centre; a wall recorded there places the point itself. On the swept side of the wall the
// material from the wall's foot up is gone. On the far side of a wall that passes between a swept
// centre and the point, the point has the material of the ray one cell across the wall. The ray's
// second (lower) wall, if any, only takes out the material on its swept side.
Ray material_at(const DexelView& stock, double ci, double cj, double x, double y, double tolerance_mm) {
    const GridInfo& g = stock.grid;
    const std::size_t index = std::size_t(cj) * g.nx + std::size_t(ci);
    Ray ray = stock.load(index);
    if (!has_wall_mark(ray.data())) return ray;
    const double du = (x - g.x0_mm) / g.cell_mm - (ci + 0.5), dv = (y - g.y0_mm) / g.cell_mm - (cj + 0.5);
    auto depth = [&](const Wall& w) { return w.clearance_mm + (du * w.nx + dv * w.ny) * g.cell_mm; };
    const Wall wall = stock.wall(index, 0), low = stock.wall(index, 1);
    double swept_from = kNoWall;   // material from this height up is gone
    if (depth(wall) <= tolerance_mm) {
        swept_from = wall.z_from_mm;
    } else if (wall.clearance_mm <= 0) {
        // One cell over, whatever the stored normal says (engage.cl clamps alike).
        const double ai = std::clamp(std::floor(ci + 0.5 + wall.nx), ci - 1, ci + 1);
        const double aj = std::clamp(std::floor(cj + 0.5 + wall.ny), cj - 1, cj + 1);
        if (ai < 0 || aj < 0 || ai >= g.nx || aj >= g.ny) return kNoMaterial;
        ray = stock.load(std::size_t(aj) * g.nx + std::size_t(ai));
    }
    if (low.exists() && depth(low) <= tolerance_mm) swept_from = std::min(swept_from, double(low.z_from_mm));
    // Float round-off must not leave the foot itself in material (a flat bottom on the floor).
    if (swept_from < kNoWall) subtract_interval(ray.data(), swept_from - kSliverMm, -kEmptyHi);
    return ray;
}

}  // namespace

void engage_twin(const StepBatch& steps, const EdgeTable& tool, const EngageParams& p, const DexelView& stock,
                 StepResult* out) {
    const GridInfo& grid = stock.grid;
    const double pitch = 2 * std::numbers::pi / tool.flutes;
    const CuttingCoefficients& k = p.k;
    for (std::size_t i = 0; i < steps.size(); ++i) {
        const double tx = steps.tip_x[i], ty = steps.tip_y[i], tz = steps.tip_z[i];
        const double fx = steps.feed_x[i], fy = steps.feed_y[i], fz = steps.feed_z[i];
        const double s = steps.spin;
        const double fxy = std::hypot(fx, fy);
        const double px = fxy > 1e-12 ? -fy / fxy : 1.0, py = fxy > 1e-12 ? fx / fxy : 0.0;
        StepSums sums;
        const int first = fz >= 0 ? tool.bottom_count : 0;
        for (int j = 0; j < tool.flutes; ++j) {
            for (int e = first; e < p.element_end; ++e) {
                const double alpha = std::numbers::pi / 2 - steps.theta_rad[i] - j * pitch + s * tool.lag_rad[e];
                const double cu = std::cos(alpha), su = std::sin(alpha);
                const double nr = tool.nr[e], nz = tool.nz[e], r = tool.r_mm[e];
                const double h = nr * (fx * cu + fy * su) + nz * fz;
                if (h <= p.min_chip_mm) continue;
                const double x = tx + r * cu, y = ty + r * su, z = tz + tool.z_mm[e];
                const double ci = std::floor((x - grid.x0_mm) / grid.cell_mm);
                const double cj = std::floor((y - grid.y0_mm) / grid.cell_mm);
                if (ci < 0 || cj < 0 || ci >= grid.nx || cj >= grid.ny) continue;
                const Ray stored = material_at(stock, ci, cj, x, y, p.wall_tolerance_mm);
                const float* ray = stored.data();
                const double span = tool.z_hi_mm[e] - tool.z_lo_mm[e];
                double weight = 0, clip_lo = z, clip_hi = z, h_cut = h;
                if (span > 0) {
                    weight = ray_overlap(ray, tz + tool.z_lo_mm[e], tz + tool.z_hi_mm[e], clip_lo, clip_hi) / span;
                } else if (ray_contains(ray, z)) {
                    // The chip is the material between this edge point and the previous tooth's pass,
                    // h above it: no more than the ray holds there.
                    double unused_lo = 0, unused_hi = 0;
                    h_cut = std::min(h, ray_overlap(ray, z, z + h, unused_lo, unused_hi));
                    if (h_cut > p.min_chip_mm) weight = 1;
                }
                if (weight <= 0) continue;
                sums.add(k, s, h_cut, tool.db_mm[e] * weight, r, tool.z_mm[e], cu, su, nr, nz, p.holder_face_z_mm, px, py,
                         clip_lo - tz, clip_hi - tz);
            }
        }
        out[i] = sums.result(sums.Fx, sums.Fy, sums.Fz);
    }
}

}  // namespace cutload::kernels
