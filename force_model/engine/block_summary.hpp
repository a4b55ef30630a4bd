// Internal: per-block summaries and overload flags from the engine's rows.
#pragma once

#include "engine/rows.hpp"
#include "force_model/force_model.hpp"

#include <vector>

namespace cutload::force_model {

std::vector<BlockSummary> summarise_blocks(const motion_io::MotionModel& motion, const std::vector<ForceSample>& rows,
                                           const std::vector<RowExtra>& extra, const Limits& limits);

}  // namespace cutload::force_model
