// Internal: stage "sequence" (see sequence.cpp).
#pragma once

#include "stages/stage.hpp"

#include <deque>

namespace cutload::motion_io::detail {

// Accepts checked readings; emits sessions and, within them, time-ordered positions (single-axis
// items, linear and rotary, merged into positions), feed, spindle and block readings.
class Sequence final : public Stage {
public:
    Sequence(Diagnostics& diag, StageLimits limits = {});
    Flows accepts() const override { return static_cast<Flows>(Flow::Checked); }
    Flows emits() const override {
        return Flow::Sessions | Flow::Positions | Flow::Feed | Flow::Spindle | Flow::Blocks;
    }
    void record(const Record& r) override;
    // The end of the stream ends the session; records pushed afterwards start a new one.
    void finish() override;

private:
    void drain(bool all);
    void release(const Record& r);
    void flush_axes();
    // A single-axis reading into the position being latched: its value, its axis known (bit k).
    void latch_axis(const Record& r, double& slot, unsigned& known, int k);
    void end_session();

    Diagnostics& diag_;
    StageLimits limits_;
    // Records in time order (equal times in file order). Logs arrive nearly sorted, so an
    // insertion from the back costs O(1) on average.
    std::deque<Record> queue_;
    bool have_max_ = false;
    double max_t_ = 0;
    bool in_session_ = false;
    double last_t_ = 0;
    Record axes_;
    unsigned axes_known_ = 0;
    unsigned rotary_known_ = 0;   // bit k: rotary axis k (A, B, C) read in this session
    bool axis_pending_ = false;
    double axis_t_ = 0;
};

}  // namespace cutload::motion_io::detail
