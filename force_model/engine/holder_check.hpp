// Internal: shank and holder contact, and holder near misses. Only the flutes cut: stock above the
// flute length inside the cutter's footprint touches the shank, stock within the holder radius
// above the stickout touches the holder. Both raise ForceSample::holder_contact. Stock within the
// holder's clearance shell (ToolGeometry::holder_clearance_mm, document 004's V_sh) without
// contact gives the rows its clearance (RowExtra::holder_clearance_mm), which the block summary
// turns into holder_near_miss (docs/force_model.md, "Removal").
#pragma once

#include "cutters/tool_geometry.hpp"
#include "engine/batcher.hpp"
#include "engine/rows.hpp"
#include "engine/stock_map.hpp"
#include "force_model/force_model.hpp"

namespace cutload::force_model {

// Marks the rows of a completed batch (rows[k], extra[k] for step k) where the shank or the holder
// touches the stock, or where the holder passes within its clearance shell, checked every few
// steps and only when the tile map says material rises that high.
void mark_holder_contact(StockMap& map, const ToolGeometry& tool, const kernels::StepBatch& steps,
                         const TipBounds& bounds, ForceSample* rows, RowExtra* extra);

// The distance from a vertical holder (radius holder_radius_mm, its face at holder_face_z_mm) to
// the stock's tops within reach_mm of it, sampled on rings as the contact check is; infinity where
// no stock is that near. Exact for stock under the holder's face: face height minus the top.
double holder_clearance_mm(const StockMap& map, double x_mm, double y_mm, double holder_radius_mm,
                           double holder_face_z_mm, double reach_mm);

}  // namespace cutload::force_model
