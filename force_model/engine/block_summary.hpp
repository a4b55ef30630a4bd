// Internal: per-block summaries and overload flags from the engine's rows.
#pragma once

#include "engine/rows.hpp"
#include "force_model/force_model.hpp"

#include <vector>

namespace cutload::force_model {

// `limits`: by the rows' cutter slot (RowExtra::slot; the tool's own limits over the run's). Rows of
// an unknown tool (slot -1) flag unknown_tool.
std::vector<BlockSummary> summarise_blocks(const motion_io::MotionModel& motion, const std::vector<ForceSample>& rows,
                                           const std::vector<RowExtra>& extra, const std::vector<Limits>& limits);

}  // namespace cutload::force_model
