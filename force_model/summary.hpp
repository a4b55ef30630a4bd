// Internal: per-block summaries and overload flags from the engine's rows.
#pragma once

#include "engine.hpp"

#include <vector>

namespace cutload::force_model {

// What the engine knows about a row beyond the public ForceSample.
struct RowExtra {
    float feed_mm_min = 0;
    float engaged = 0;                 // engaged edge elements
    bool stopped_in_material = false;  // |rpm| < 1 with the cutter in material
    float spindle_rpm = 0;
};

std::vector<BlockSummary> summarise_blocks(const motion_io::MotionModel& motion, const std::vector<ForceSample>& rows,
                                           const std::vector<RowExtra>& extra, const Limits& limits);

}  // namespace cutload::force_model
