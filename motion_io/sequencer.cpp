// Stage "align channels": puts records in time order, splits sessions, merges single-axis
// position items into 3-D positions and, for event-driven logs, makes "value held" explicit.
#include "sequencer.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace cutload::motion_io::detail {

Sequencer::Sequencer(Diagnostics& diag, SessionConsumer& out, bool event_driven, StageLimits limits)
    : diag_(diag), out_(out), event_driven_(event_driven), limits_(limits) {}

void Sequencer::push(const Record& r) {
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

void Sequencer::finish() {
    drain(true);
    end_session();
}

void Sequencer::drain(bool all) {
    while (!queue_.empty() && (all || queue_.front().t_s < max_t_ - limits_.reorder_horizon_s)) {
        const Record r = queue_.front();
        queue_.pop_front();
        release(r);
    }
}

void Sequencer::release(const Record& r) {
    if (in_session_ && r.t_s - last_t_ > limits_.session_gap_s) {
        diag_.warn("session_gap", r.line,
                   fmt::format("no record for {:.1f} s (more than {} s): a new session starts", r.t_s - last_t_,
                               limits_.session_gap_s));
        end_session();
    }
    if (!in_session_) {
        out_.begin_session();
        in_session_ = true;
    }
    if (axis_pending_ && r.t_s != axis_t_) flush_axes();
    last_t_ = r.t_s;
    switch (r.ch) {
        case Chan::AxisX: case Chan::AxisY: case Chan::AxisZ: {
            const int k = static_cast<int>(r.ch) - static_cast<int>(Chan::AxisX);
            axes_.v[k] = r.v[0];
            axes_known_ |= 1u << k;
            axes_.line = r.line;
            axis_t_ = r.t_s;
            axis_pending_ = true;
            break;
        }
        case Chan::Pos: case Chan::Spindle:
            forward_held(r);
            break;
        default:
            out_.record(r);
    }
}

void Sequencer::flush_axes() {
    axis_pending_ = false;
    if (axes_known_ != 7u) {
        diag_.warn("axis_incomplete", axes_.line, "position item before all three axes were known; skipped");
        return;
    }
    Record p = axes_;
    p.ch = Chan::Pos;
    p.t_s = axis_t_;
    forward_held(p);
}

// An event-driven adapter sends a value only when it changes, so silence means "unchanged". The
// next value after a silence longer than the usual update interval started to change at most one
// interval earlier: a copy of the held value there stops interpolation from smearing the move
// over the whole silence.
void Sequencer::forward_held(const Record& r) {
    Held& h = r.ch == Chan::Pos ? held_pos_ : held_spindle_;
    if (event_driven_ && h.have) {
        const double dt = r.t_s - h.last.t_s;
        if (h.n_intervals >= 3) {
            std::array<double, kIntervalRing> sorted = h.intervals;
            const std::size_t n = std::min(h.n_intervals, kIntervalRing);
            std::nth_element(sorted.begin(), sorted.begin() + static_cast<long>(n / 2), sorted.begin() + static_cast<long>(n));
            const double usual = sorted[n / 2];
            if (dt > 2 * usual) {
                Record hold = h.last;
                hold.t_s = r.t_s - usual;
                hold.line = r.line;
                out_.record(hold);
            }
        }
        if (dt > 0) h.intervals[h.n_intervals++ % kIntervalRing] = dt;
    }
    h.last = r;
    h.have = true;
    out_.record(r);
}

void Sequencer::end_session() {
    if (!in_session_) return;
    if (axis_pending_) flush_axes();
    out_.end_session();
    in_session_ = false;
    held_pos_ = Held{};
    held_spindle_ = Held{};
    axes_known_ = 0;
}

}  // namespace cutload::motion_io::detail
