#include "stages/jumps.hpp"

#include <fmt/format.h>

#include <cmath>

namespace cutload::motion_io::detail {
namespace {

double distance_mm(const Record& a, const Record& b) {
    return std::sqrt((a.v[0] - b.v[0]) * (a.v[0] - b.v[0]) + (a.v[1] - b.v[1]) * (a.v[1] - b.v[1]) +
                     (a.v[2] - b.v[2]) * (a.v[2] - b.v[2]));
}

}  // namespace

DropJumps::DropJumps(Diagnostics& diag, JumpLimits limits)
    : Stage("drop_jumps"), diag_(diag), limits_(limits), max_speed_mm_s_(limits.max_speed_mm_min / 60.0) {}

void DropJumps::begin_session() {
    anchor_.reset();
    held_.clear();
    emit_begin_session();
}

bool DropJumps::reachable(const Record& from, const Record& to) const {
    const double reach = max_speed_mm_s_ * (std::fabs(to.t_s - from.t_s) + limits_.slack_s) + limits_.slack_mm;
    return distance_mm(from, to) <= reach;
}

void DropJumps::record(const Record& r) {
    if (anchor_)
        follow(r);
    else
        start_up(r);
}

// No anchor yet: hold readings until two consecutive ones agree.
void DropJumps::start_up(const Record& r) {
    held_.push_back(r);
    const std::size_t n = held_.size();
    if (n >= 2 && reachable(held_[n - 2], held_[n - 1]))
        settle_start(n - 1);
    else if (n >= limits_.max_glitch_readings)
        accept_excursion();   // nothing agrees with anything: no basis to drop any of it
}

// held_[pair_end - 1] and held_[pair_end] agree: the earlier readings that cannot reach the pair
// are glitches, the rest is motion.
void DropJumps::settle_start(std::size_t pair_end) {
    const Record& first = held_[pair_end - 1];
    std::vector<Record> glitches;
    for (std::size_t k = 0; k + 1 < pair_end; ++k)
        if (!reachable(held_[k], first)) glitches.push_back(held_[k]);
    if (!glitches.empty()) drop(glitches, first, "the readings after it agree with each other");
    std::vector<Record> keep;
    keep.swap(held_);
    for (std::size_t k = 0; k < keep.size(); ++k)
        if (k + 1 >= pair_end || reachable(keep[k], first)) accept(keep[k]);
}

void DropJumps::follow(const Record& r) {
    if (held_.empty()) {
        if (reachable(*anchor_, r))
            accept(r);
        else
            held_.push_back(r);
        return;
    }
    const bool from_anchor = reachable(*anchor_, r);
    const bool from_last = reachable(held_.back(), r);
    if (from_anchor && !from_last) {   // away and back: the excursion was a glitch
        drop(held_, *anchor_, "the log comes back");
        held_.clear();
        Record back = r;
        back.after_glitch = true;
        accept(back);
    } else if (from_anchor) {          // the log goes on from where the excursion went
        accept_excursion();
        accept(r);
    } else {
        held_.push_back(r);
        if (held_.size() >= limits_.max_glitch_readings) accept_excursion();
    }
}

void DropJumps::accept(const Record& r) {
    anchor_ = r;
    emit(Flow::Positions, r);
}

// Kept: the log stays where it jumped to. With an anchor, the jump itself was beyond reach.
void DropJumps::accept_excursion() {
    if (anchor_) {
        const Record& a = *anchor_;
        const Record& b = held_.front();
        const double dt = b.t_s - a.t_s;
        diag_.warn("position_jump", b.line,
                   fmt::format("position jumps {:.3f} mm in {:.4f} s (faster than {:g} m/min) and the next {} readings "
                               "follow on from there: kept as real (lost readings, or a restart?)",
                               distance_mm(a, b), dt, limits_.max_speed_mm_min / 1000, held_.size() - 1));
    }
    std::vector<Record> keep;
    keep.swap(held_);
    for (const Record& r : keep) accept(r);
}

void DropJumps::drop(const std::vector<Record>& readings, const Record& from, const char* why) {
    const Record& g = readings.front();
    const double dt = std::fabs(g.t_s - from.t_s);
    const double speed_m_min = dt > 0 ? distance_mm(from, g) / dt * 60.0 / 1000.0 : INFINITY;
    const std::string what =
        fmt::format("position ({:g}, {:g}, {:g}) mm is {:.3f} mm from a reading {:.4f} s away ({:.0f} m/min, "
                    "faster than any machine's {:g} m/min) and {}: a glitch, dropped",
                    g.v[0], g.v[1], g.v[2], distance_mm(from, g), dt, speed_m_min, limits_.max_speed_mm_min / 1000, why);
    for (const Record& r : readings) diag_.warn("glitch_dropped", r.line, what);   // counted once per reading
    dropped_ += readings.size();
}

void DropJumps::end_session(SessionSummary& s) {
    if (!anchor_)
        accept_excursion();   // too few readings to tell: all kept
    else if (!held_.empty()) {
        drop(held_, *anchor_, "the session ends before the log comes back");
        held_.clear();
    }
    emit_end_session(s);
}

}  // namespace cutload::motion_io::detail
