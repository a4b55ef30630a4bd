#include "engine/batcher.hpp"

#include <algorithm>
#include <numbers>

namespace cutload::force_model {

StepBatcher::StepBatcher(const EngineSettings& settings, double cell_mm)
    : max_steps_(settings.max_batch_steps), cos_turn_(std::cos(settings.batch_turn_deg * std::numbers::pi / 180)),
      cell_mm_(cell_mm) {
    steps_.reserve(max_steps_);
    meta_.reserve(max_steps_);
}

TipBounds StepBatcher::tip_bounds() const {
    TipBounds b;
    b.x0_mm = b.y0_mm = 1e300;
    b.x1_mm = b.y1_mm = -1e300;
    b.z_min_mm = 1e300;
    for (std::size_t k = 0; k < steps_.size(); ++k) {
        b.x0_mm = std::min(b.x0_mm, steps_.tip_x[k]);
        b.x1_mm = std::max(b.x1_mm, steps_.tip_x[k]);
        b.y0_mm = std::min(b.y0_mm, steps_.tip_y[k]);
        b.y1_mm = std::max(b.y1_mm, steps_.tip_y[k]);
        b.z_min_mm = std::min(b.z_min_mm, steps_.tip_z[k]);
    }
    return b;
}

void StepBatcher::hand_over(kernels::StepBatch& steps, std::vector<StepMeta>& meta) {
    std::swap(steps, steps_);
    std::swap(meta, meta_);
    steps_.clear();
    meta_.clear();
}

}  // namespace cutload::force_model
