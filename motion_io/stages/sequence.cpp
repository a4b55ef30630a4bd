// Stage "sequence": puts records in time order and splits sessions (a jump back in time beyond the
// reorder horizon, or a long silence), and merges single-axis position items into 3-D positions.
//
// Rotary items (SHDR A, B, C: ReaderFacts::rotary_items) are latched the same way: every position
// carries the last value of each rotary axis the log has, and a rotary item alone (a table turning
// while X, Y, Z stand still: an adapter sends only what changes) makes a position too. A 3-D path
// position then joins the merge as all three linear axes at once, so one time stamp gives one
// position with every axis. Until every axis of the log has been read in a session, positions are
// skipped (axis_incomplete): an axis's position is not invented.
#include "stages/sequence.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace cutload::motion_io::detail {

Sequence::Sequence(Diagnostics& diag, StageLimits limits) : Stage("sequence"), diag_(diag), limits_(limits) {}

void Sequence::record(const Record& r) {
    if (have_max_) {
        if (r.t_s < max_t_ - limits_.reorder_horizon_s) {
            // A restart dump or another recording: everything before belongs to the old session.
            diag_.warn("session_backwards", r.line,
                       fmt::format("time jumps back by {:.3f} s: a new session starts", max_t_ - r.t_s));
            drain(true);
            end_session();
            have_max_ = false;
        } else if (r.t_s < max_t_) {
            diag_.warn("time_backwards", r.line,
                       fmt::format("record {:.3f} s older than one already read; reordered (jumps up to {} s are "
                                   "reordered, larger ones start a session)",
                                   max_t_ - r.t_s, limits_.reorder_horizon_s));
        }
    }
    if (queue_.empty() || r.t_s >= queue_.back().t_s) {
        queue_.push_back(r);
    } else {
        const auto at = std::upper_bound(queue_.begin(), queue_.end(), r.t_s,
                                         [](double t, const Record& q) { return t < q.t_s; });
        queue_.insert(at, r);
    }
    if (!have_max_ || r.t_s > max_t_) max_t_ = r.t_s;
    have_max_ = true;
    drain(false);
}

void Sequence::finish() {
    drain(true);
    end_session();
}

void Sequence::drain(bool all) {
    while (!queue_.empty() && (all || queue_.front().t_s < max_t_ - limits_.reorder_horizon_s)) {
        const Record r = queue_.front();
        queue_.pop_front();
        release(r);
    }
}

void Sequence::release(const Record& r) {
    if (in_session_ && r.t_s - last_t_ > limits_.session_gap_s) {
        diag_.warn("session_gap", r.line,
                   fmt::format("no record for {:.1f} s (more than {} s): a new session starts", r.t_s - last_t_,
                               limits_.session_gap_s));
        end_session();
    }
    if (!in_session_) {
        emit_begin_session();
        in_session_ = true;
    }
    if (axis_pending_ && r.t_s != axis_t_) flush_axes();
    last_t_ = r.t_s;
    switch (r.ch) {
        case Chan::AxisX: case Chan::AxisY: case Chan::AxisZ: {
            const int k = static_cast<int>(r.ch) - static_cast<int>(Chan::AxisX);
            latch_axis(r, axes_.v[k], axes_known_, k);
            break;
        }
        case Chan::AxisA: case Chan::AxisB: case Chan::AxisC: {
            const int k = static_cast<int>(r.ch) - static_cast<int>(Chan::AxisA);
            latch_axis(r, axes_.rot_deg[k], rotary_known_, k);
            break;
        }
        case Chan::Pos:
            if (diag_.facts().rotary_items) {
                for (int k = 0; k < 3; ++k) axes_.v[k] = r.v[k];
                axes_.after_glitch = axes_.after_glitch || r.after_glitch;
                axes_known_ = 7u;
                axes_.line = r.line;
                axis_t_ = r.t_s;
                axis_pending_ = true;
                break;
            }
            emit(Flow::Positions, r);
            break;
        default:
            emit(session_flow(r.ch), r);
    }
}

void Sequence::latch_axis(const Record& r, double& slot, unsigned& known, int k) {
    slot = r.v[0];
    axes_.after_glitch = axes_.after_glitch || r.after_glitch;
    known |= 1u << k;
    axes_.line = r.line;
    axis_t_ = r.t_s;
    axis_pending_ = true;
}

void Sequence::flush_axes() {
    axis_pending_ = false;
    if (axes_known_ != 7u) {
        diag_.warn("axis_incomplete", axes_.line, "position item before all three axes were known; skipped");
        return;
    }
    unsigned rotary_needed = 0;
    for (unsigned k = 0; k < 3; ++k)
        if (diag_.facts().rotary_items && diag_.facts().rotary[k]) rotary_needed |= 1u << k;
    if ((rotary_known_ & rotary_needed) != rotary_needed) {
        const unsigned missing = rotary_needed & ~rotary_known_;
        std::string axes;
        for (unsigned k = 0; k < 3; ++k)
            if (missing & (1u << k)) axes += fmt::format("{}{}", axes.empty() ? "" : ", ", char('A' + k));
        diag_.warn("axis_incomplete", axes_.line,
                   fmt::format("position before rotary axis {} was known in this session; skipped", axes));
        return;
    }
    Record p = axes_;
    axes_.after_glitch = false;
    p.ch = Chan::Pos;
    p.t_s = axis_t_;
    emit(Flow::Positions, p);
}

void Sequence::end_session() {
    if (!in_session_) return;
    if (axis_pending_) flush_axes();
    SessionSummary summary;
    emit_end_session(summary);
    in_session_ = false;
    axes_known_ = 0;
    rotary_known_ = 0;
}

}  // namespace cutload::motion_io::detail
