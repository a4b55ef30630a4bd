#include "engine/removal_path.hpp"

#include <algorithm>
#include <cmath>

namespace cutload::force_model {

namespace {

constexpr std::size_t kMaxChordPoints = 128;      // bounds the quadratic chord check
constexpr std::size_t kMaxSegmentsPerCall = 64;

}  // namespace

RemovalPath::RemovalPath(double cell_mm, double cutter_radius_mm, double lag_mm, double chord_tolerance_mm)
    : cell_mm_(cell_mm), cutter_radius_mm_(cutter_radius_mm), lag_mm_(lag_mm), chord_tolerance_mm_(chord_tolerance_mm) {}

void RemovalPath::add(const Vec3& p, bool keep) {
    if (pending_.empty()) {
        pending_.push_back({p, path_mm_});
        return;
    }
    const Vec3& q = pending_.back().tip_mm;
    const double d2 = (p.x - q.x) * (p.x - q.x) + (p.y - q.y) * (p.y - q.y) + (p.z - q.z) * (p.z - q.z);
    if (!keep && d2 < 0.25 * cell_mm_ * cell_mm_) return;
    path_mm_ += std::sqrt(d2);
    pending_.push_back({p, path_mm_});
}

void RemovalPath::add_batch(const kernels::StepBatch& steps) {
    const std::size_t n = steps.size();
    for (std::size_t k = 0; k < n; ++k) add({steps.tip_x[k], steps.tip_y[k], steps.tip_z[k]}, k + 1 == n);
}

void RemovalPath::take(bool keep_lag, StockMap& map, std::vector<kernels::SweepSegment>& segs,
                       std::vector<kernels::SweepCall>& calls) {
    if (pending_.empty()) return;
    std::size_t last = pending_.size() - 1;
    if (keep_lag) {
        const double s_cut = pending_.back().s_mm - lag_mm_;
        std::size_t m = 0;
        while (m + 1 < pending_.size() && pending_[m + 1].s_mm <= s_cut) ++m;
        if (m == 0) return;
        last = m;
    }
    std::size_t call_begin = segs.size();
    double call_len_mm = 0;
    auto end_call = [&] {
        if (segs.size() > call_begin) add_call(call_begin, map, segs, calls);
        call_begin = segs.size();
        call_len_mm = 0;
    };
    if (last == 0) {
        const Vec3& p = pending_[0].tip_mm;
        segs.push_back({p.x, p.y, p.z, p.x, p.y, p.z});
        end_call();
    }
    // Calls cover at most 4R of path: tight cell rectangles.
    for (std::size_t a = 0; a < last;) {
        const std::size_t b = chord_end(a, last);
        const Vec3 &pa = pending_[a].tip_mm, &pb = pending_[b].tip_mm;
        segs.push_back({pa.x, pa.y, pa.z, pb.x, pb.y, pb.z});
        call_len_mm += distance_mm(pa, pb);
        if (call_len_mm > 4 * cutter_radius_mm_ || segs.size() - call_begin >= kMaxSegmentsPerCall) end_call();
        a = b;
    }
    end_call();
    if (keep_lag) pending_.erase(pending_.begin(), pending_.begin() + std::ptrdiff_t(last));
    else {
        // Nothing pending: the next path measures from zero, so a walk resumed here (a stock
        // checkpoint) measures its lag exactly as the whole run does.
        pending_.clear();
        path_mm_ = 0;
    }
}

void RemovalPath::add_call(std::size_t first, StockMap& map, std::vector<kernels::SweepSegment>& segs,
                           std::vector<kernels::SweepCall>& calls) const {
    const double reach_mm = cutter_radius_mm_ + cell_mm_;
    double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300, z_min = 1e300;
    for (std::size_t k = first; k < segs.size(); ++k) {
        const auto& s = segs[k];
        x0 = std::min({x0, s.ax, s.bx});
        x1 = std::max({x1, s.ax, s.bx});
        y0 = std::min({y0, s.ay, s.by});
        y1 = std::max({y1, s.ay, s.by});
        z_min = std::min({z_min, s.az, s.bz});
    }
    // Nothing to cut where no material rises above the tip (by the tops as of the last completion).
    CellRect cells;
    if (!map.cells_covering(x0 - reach_mm, y0 - reach_mm, x1 + reach_mm, y1 + reach_mm, cells) ||
        map.max_top(x0 - reach_mm, y0 - reach_mm, x1 + reach_mm, y1 + reach_mm) <= z_min) {
        segs.resize(first);
        return;
    }
    kernels::SweepCall c;
    c.first_segment = first;
    c.segments = segs.size() - first;
    c.i0 = cells.i0;
    c.j0 = cells.j0;
    c.width = cells.i1 - cells.i0;
    c.height = cells.j1 - cells.j0;
    calls.push_back(c);
}

// The farthest point b <= last (at most kMaxChordPoints on) such that every point between a and b
// stays within the chord tolerance of the chord and the chord is at most 2R long. Binary search: a
// check costs O(b - a), so growing one point at a time would be quadratic.
std::size_t RemovalPath::chord_end(std::size_t a, std::size_t last) const {
    std::size_t good = a + 1, bad = std::min(last, a + kMaxChordPoints) + 1;
    if (chord_ok(a, bad - 1)) return bad - 1;
    while (bad - good > 1) {
        const std::size_t mid = good + (bad - good) / 2;
        (chord_ok(a, mid) ? good : bad) = mid;
    }
    return good;
}

bool RemovalPath::chord_ok(std::size_t a, std::size_t b) const {
    const Vec3 &pa = pending_[a].tip_mm, &pb = pending_[b].tip_mm;
    const double len = distance_mm(pa, pb);
    if (len > 2 * cutter_radius_mm_) return false;
    if (len < 1e-12) return true;
    const double tol = chord_tolerance_mm_;
    const double ux = (pb.x - pa.x) / len, uy = (pb.y - pa.y) / len, uz = (pb.z - pa.z) / len;
    for (std::size_t k = a + 1; k < b; ++k) {
        const Vec3& p = pending_[k].tip_mm;
        const double wx = p.x - pa.x, wy = p.y - pa.y, wz = p.z - pa.z;
        const double along = wx * ux + wy * uy + wz * uz;
        const double off2 = wx * wx + wy * wy + wz * wz - along * along;
        if (off2 > tol * tol) return false;
    }
    return true;
}

}  // namespace cutload::force_model
