// Internal: shank and holder contact. Only the flutes cut: stock above the flute length inside the
// cutter's footprint touches the shank, stock within the holder radius above the stickout touches
// the holder. Both raise ForceSample::holder_contact (docs/force_model.md, "Removal").
#pragma once

#include "cutters/tool_geometry.hpp"
#include "engine/batcher.hpp"
#include "engine/stock_map.hpp"
#include "force_model/force_model.hpp"

namespace cutload::force_model {

// Marks the rows of a completed batch (rows[k] for step k) where the shank or the holder touches
// the stock, checked every few steps and only when the tile map says material rises that high.
void mark_holder_contact(StockMap& map, const ToolGeometry& tool, const kernels::StepBatch& steps,
                         const TipBounds& bounds, ForceSample* rows);

}  // namespace cutload::force_model
