#include "stages/stale.hpp"

namespace cutload::motion_io::detail {
namespace {

// Every axis, rotary ones too: a table turning while X, Y, Z stand still is no repeat.
bool same_position(const Record& a, const Record& b) {
    for (int k = 0; k < 3; ++k)
        if (a.v[k] != b.v[k] || a.rot_deg[k] != b.rot_deg[k]) return false;
    return true;
}

}  // namespace

void StaleRepeats::begin_session() {
    prev2_.reset(), prev1_.reset(), held_.reset();
    emit_begin_session();
}

void StaleRepeats::record(const Record& r) {
    if (held_) {
        settle_held(!same_position(r, *held_));
        prev2_ = prev1_;
        prev1_ = held_;
    }
    held_ = r;
}

// The held reading repeats the one before it: stale if the machine moves around it.
void StaleRepeats::settle_held(bool next_differs) {
    const bool repeat = prev1_ && same_position(*held_, *prev1_);
    const bool moving = (prev1_ && prev2_ && !same_position(*prev1_, *prev2_)) || next_differs;
    if (repeat && moving) {
        ++dropped_;
        diag_.warn("stale_repeat", held_->line, "position read again before the CNC updated it; dropped");
    } else {
        emit(Flow::Positions, *held_);
    }
}

void StaleRepeats::end_session(SessionSummary& s) {
    if (held_) {
        settle_held(false);   // the last reading: no next one to differ
        held_.reset();
    }
    emit_end_session(s);
}

void StaleRepeats::report(IngestReport& report) const { report.channels["pos"].stale_dropped = dropped_; }

}  // namespace cutload::motion_io::detail
