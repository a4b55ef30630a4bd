#include "stages/resample.hpp"

#include "motion_io/hermite.hpp"

#include <algorithm>
#include <cmath>

namespace cutload::motion_io::detail {
namespace {

// Samples handed on at once: a long segment (a silence at a fine step) goes in several batches.
constexpr std::size_t kMaxBatch = 256;

}  // namespace

Resample::Resample(Diagnostics& diag, double step_s) : Stage("resample"), diag_(diag), step_s_(step_s) {
    batch_.reserve(kMaxBatch);
}

void Resample::knot(const Knot& k) {
    if (!prev_) {
        // The readers know the log's axes before its first reading.
        rotary_mask_ = 0;
        for (std::size_t a = 0; a < 3; ++a)
            if (diag_.facts().rotary[a]) rotary_mask_ |= std::uint8_t(1u << a);
    }
    if (prev_) emit_until(*prev_, k, false);
    before_prev_ = prev_;
    prev_ = k;
}

void Resample::begin_session() {
    prev_.reset();
    before_prev_.reset();
    have_grid_ = false;
    grid_i_ = 0;
    emit_begin_session();
}

void Resample::end_session(SessionSummary& s) {
    // The grid time that falls on the last knot, if one does.
    if (before_prev_) emit_until(*before_prev_, *prev_, true);
    if (s.position_reads > 0 && !have_grid_)
        diag_.warn("session_too_short", s.first_line, "session without motion to resample (a single position)");
    emit_end_session(s);
}

void Resample::emit_until(const Knot& a, const Knot& b, bool include_end) {
    if (!have_grid_) {
        grid_t0_ = a.t_s;
        grid_i_ = 0;
        have_grid_ = true;
    }
    const double h = b.t_s - a.t_s;
    while (true) {
        const double t = grid_t0_ + static_cast<double>(grid_i_) * step_s_;
        if (!(t < b.t_s || (include_end && t <= b.t_s + 1e-12))) break;
        ++grid_i_;
        const double u = std::clamp((t - a.t_s) / h, 0.0, 1.0);
        GridSample s;
        s.t_s = t;
        s.rotary = rotary_mask_;
        for (int ax = 0; ax < 3; ++ax) {
            const HermiteSegment seg{a.p_mm[ax], a.v_mm_s[ax], b.p_mm[ax], b.v_mm_s[ax], h};
            s.p_mm[ax] = seg.position(u);
            s.v_mm_s[ax] = seg.velocity(u);
            if (!(rotary_mask_ & (1u << ax))) continue;   // three-axis logs pay nothing here
            const HermiteSegment rot{a.rot_deg[ax], a.rot_vel_deg_s[ax], b.rot_deg[ax], b.rot_vel_deg_s[ax], h};
            s.rot_deg[ax] = rot.position(u);
            s.rot_vel_deg_s[ax] = rot.velocity(u);
        }
        note_feed(s);
        batch_.push_back(s);
        if (batch_.size() == kMaxBatch) flush_batch();
    }
    flush_batch();
}

void Resample::flush_batch() {
    if (batch_.empty()) return;
    emit(std::span<GridSample>(batch_));
    batch_.clear();
}

void Resample::note_feed(const GridSample& s) {
    double speed2 = 0;
    for (int ax = 0; ax < 3; ++ax) speed2 += s.v_mm_s[ax] * s.v_mm_s[ax];
    const double f = std::sqrt(speed2) * 60.0;
    feed_min_ = have_feed_ ? std::min(feed_min_, f) : f;
    feed_max_ = have_feed_ ? std::max(feed_max_, f) : f;
    if (!have_feed_) first_position_mm_ = {s.p_mm[0], s.p_mm[1], s.p_mm[2]};
    have_feed_ = true;
}

void Resample::report(IngestReport& report) const {
    report.feed_repaired_min_mm_min = feed_min_;
    report.feed_repaired_max_mm_min = feed_max_;
    if (have_feed_) report.first_position_mm = first_position_mm_;
}

}  // namespace cutload::motion_io::detail
