// Internal: stage "validate" - no reading outside what a machine can physically report passes.
#pragma once

#include "stages/stage.hpp"

namespace cutload::motion_io::detail {

// Beyond these no wrong unit explains a value (the readers' plausible limits, StageLimits, times
// the largest factor a unit mix-up gives): it is a glitch. Between the two a value is kept with
// the readers' out_of_range warning, so a log with a wrong unit is still read and says so.
struct PhysicalLimits {
    double max_abs_position_mm = 1e7;    // 10 m x 1000 (um read as mm)
    double max_abs_feed_mm_min = 1.2e7;  // 200 m/min x 60 (per-minute values read as per-second)
    double max_abs_spindle_rpm = 6e6;    // 100000 rpm x 60 (rpm read as rev/s)
};

// Accepts readings, emits checked readings. A reading with a non-finite time or value, or a value
// beyond PhysicalLimits, is dropped with a `glitch_dropped` warning naming the line, the channel
// and the value. (The file readers already stop at a non-finite number; a live source pushes
// records past no reader.)
class Validate final : public Stage {
public:
    Validate(Diagnostics& diag, PhysicalLimits limits = {});
    Flows accepts() const override { return static_cast<Flows>(Flow::Readings); }
    Flows emits() const override { return static_cast<Flows>(Flow::Checked); }
    void record(const Record& r) override;
    std::size_t dropped() const { return dropped_; }

private:
    double limit_for(Chan ch) const;
    bool glitch(const Record& r) const;
    void drop(const Record& r);

    Diagnostics& diag_;
    PhysicalLimits limits_;
    std::size_t dropped_ = 0;
};

}  // namespace cutload::motion_io::detail
