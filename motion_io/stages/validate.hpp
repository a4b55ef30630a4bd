// Internal: stage "validate" - no reading outside what a machine can physically report passes.
#pragma once

#include "stages/stage.hpp"

#include <cstddef>
#include <optional>

namespace cutload::motion_io::detail {

// Beyond these no wrong unit explains a value (the readers' plausible limits, StageLimits, times
// the largest factor a unit mix-up gives): it is a glitch. Between the two a value is kept with
// the readers' out_of_range warning, so a log with a wrong unit is still read and says so.
struct PhysicalLimits {
    double max_abs_position_mm = 1e7;    // 10 m x 1000 (um read as mm)
    double max_abs_feed_mm_min = 1.2e7;  // 200 m/min x 60 (per-minute values read as per-second)
    double max_abs_spindle_rpm = 6e6;    // 100000 rpm x 60 (rpm read as rev/s)
    // A spindle reading beyond the plausible speed (StageLimits) that jumps there from a reading
    // spike_ratio times slower is a spike, not a unit: a unit mix-up moves the whole channel and a
    // spindle only ramps. Up to max_spike_readings in a row are dropped; a level held longer is
    // the channel's own (kept, with the readers' out_of_range warning).
    double plausible_spindle_rpm = StageLimits{}.max_abs_spindle_rpm;
    double spike_ratio = 10;
    std::size_t max_spike_readings = 32;
};

// Accepts readings, emits checked readings. A reading with a non-finite time or value, a value
// beyond PhysicalLimits, or a spindle spike is dropped with a `glitch_dropped` warning naming the
// line, the channel and the value. (The file readers already stop at a non-finite number; a live
// source pushes records past no reader.) The highest spindle speed that passes goes to the
// report (ReaderFacts::spindle_max_abs_rpm), so a dropped glitch never sets the tooth period the
// sampling check judges by.
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
    bool spike(const Record& r);
    void drop(const Record& r);
    void drop_spike(const Record& r);

    Diagnostics& diag_;
    PhysicalLimits limits_;
    std::size_t dropped_ = 0;
    // Per channel group (positions, spindle, others): a reading was dropped since the last one
    // passed on; the next one carries Record::after_glitch.
    bool dropped_since_[3] = {false, false, false};
    std::optional<double> last_spindle_rpm_;   // the last spindle reading passed on
    std::size_t spike_run_ = 0;                // spindle readings dropped as a spike since then
};

}  // namespace cutload::motion_io::detail
