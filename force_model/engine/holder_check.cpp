#include "engine/holder_check.hpp"

#include <algorithm>

namespace cutload::force_model {

namespace {

constexpr std::size_t kHolderCheckStride = 16;   // steps per check; a hit marks all of them

}  // namespace

void mark_holder_contact(StockMap& map, const ToolGeometry& tool, const kernels::StepBatch& steps,
                         const TipBounds& b, ForceSample* rows) {
    const double Rh = tool.holder_radius_mm;
    if (map.max_top(b.x0_mm - Rh, b.y0_mm - Rh, b.x1_mm + Rh, b.y1_mm + Rh) <= b.z_min_mm + tool.flute_length_mm) return;
    const std::size_t n = steps.size();
    for (std::size_t k = 0; k < n; k += kHolderCheckStride) {
        const double x = steps.tip_x[k], y = steps.tip_y[k], z = steps.tip_z[k];
        const bool contact = map.material_above(x, y, 0, tool.radius_mm * 0.98, z + tool.flute_length_mm + 1e-3) ||
                             map.material_above(x, y, tool.radius_mm, Rh, z + tool.stickout_mm + 1e-3);
        if (!contact) continue;
        for (std::size_t r = k; r < std::min(n, k + kHolderCheckStride); ++r) rows[r].holder_contact = true;
    }
}

}  // namespace cutload::force_model
