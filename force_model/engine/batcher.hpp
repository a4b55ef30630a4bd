// Internal: gathers time steps into batches for the engagement kernel. A batch ends at a block
// change, at a change of spindle direction, when full, or when the feed direction has turned by
// more than the batch turn once the tool has moved a grid cell in it (docs/force_model.md, "Time
// steps, batches and air" and "Stock lag"): the stock is only updated between batches.
#pragma once

#include "engine/motion_walk.hpp"
#include "force_model/engine_settings.hpp"
#include "kernels/engine_kernels.hpp"

#include <cstdint>
#include <vector>

namespace cutload::force_model {

// What a row needs of a step beyond the kernel's inputs.
struct StepMeta {
    double t_s, angle_deg, feed_mm_min, rpm;
    std::int32_t block;
};

// The box around a batch's tip positions (stock coordinates).
struct TipBounds {
    double x0_mm = 0, y0_mm = 0, x1_mm = 0, y1_mm = 0, z_min_mm = 0;
};

class StepBatcher {
public:
    StepBatcher(const EngineSettings& settings, double cell_mm);

    std::size_t size() const { return steps_.size(); }
    double spin() const { return steps_.spin; }
    const kernels::StepBatch& steps() const { return steps_; }
    // Whether the batch must end before `s` joins it (never for an empty batch).
    bool ends_before(const TimeStep& s) const;
    void add(const TimeStep& s, double spin);
    TipBounds tip_bounds() const;
    // Hands the batch over (swapping buffers, so neither side reallocates) and starts an empty one.
    void hand_over(kernels::StepBatch& steps, std::vector<StepMeta>& meta);
    // Drops the batch (its removal taken by the caller) and starts an empty one.
    void discard() {
        steps_.clear();
        meta_.clear();
    }

private:
    kernels::StepBatch steps_;
    std::vector<StepMeta> meta_;
    std::int32_t block_ = -1;
    bool has_direction_ = false;
    Vec3 direction_;   // unit feed direction at the batch's first moving step
    std::size_t max_steps_;
    double cos_turn_, cell_mm_;
};

inline bool StepBatcher::ends_before(const TimeStep& s) const {
    // Slower moves have no meaningful direction.
    constexpr double kMovingSpeed_mm_s = 0.5;
    if (steps_.size() == 0) return false;
    if (s.block != block_ || steps_.size() >= max_steps_) return true;
    const Vec3& v = s.velocity_mm_s;
    if (!(s.speed_mm_s > kMovingSpeed_mm_s && has_direction_ &&
          v.x * direction_.x + v.y * direction_.y + v.z * direction_.z < cos_turn_ * s.speed_mm_s))
        return false;
    // A turn only ends the batch once the tool has moved a grid cell since it began: the flush could
    // not change the stock before that (removal trails by several cells), so a sharp corner does
    // not splinter into one-step batches.
    const double dx = s.tip_mm.x - steps_.tip_x.front(), dy = s.tip_mm.y - steps_.tip_y.front(),
                 dz = s.tip_mm.z - steps_.tip_z.front();
    return dx * dx + dy * dy + dz * dz >= cell_mm_ * cell_mm_;
}

inline void StepBatcher::add(const TimeStep& s, double spin) {
    constexpr double kMovingSpeed_mm_s = 0.5;
    if (steps_.size() == 0) {
        block_ = s.block;
        steps_.spin = spin;
        has_direction_ = false;
    }
    if (!has_direction_ && s.speed_mm_s > kMovingSpeed_mm_s) {
        const Vec3& v = s.velocity_mm_s;
        direction_ = {v.x / s.speed_mm_s, v.y / s.speed_mm_s, v.z / s.speed_mm_s};
        has_direction_ = true;
    }
    steps_.tip_x.push_back(s.tip_mm.x);
    steps_.tip_y.push_back(s.tip_mm.y);
    steps_.tip_z.push_back(s.tip_mm.z);
    steps_.feed_x.push_back(s.feed_per_tooth_mm.x);
    steps_.feed_y.push_back(s.feed_per_tooth_mm.y);
    steps_.feed_z.push_back(s.feed_per_tooth_mm.z);
    steps_.theta_rad.push_back(s.theta_rad);
    steps_.cos_a.push_back(s.cos_a);
    steps_.sin_a.push_back(s.sin_a);
    meta_.push_back({s.t_s, s.angle_deg, s.speed_mm_s * 60, s.rpm, s.block});
}

}  // namespace cutload::force_model
