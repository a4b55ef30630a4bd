#include "engine/block_summary.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace cutload::force_model {

namespace {

void trip(BlockSummary& b, const char* flag, double t_s, double value, std::int32_t tool) {
    for (const FlagHit& f : b.flags)
        if (f.flag == flag) return;   // keep the first time it tripped
    b.flags.push_back({flag, t_s, value, tool});
}

// holder_near_miss carries the block's smallest clearance, not the first one.
void nearest(BlockSummary& b, const char* flag, double t_s, double value, std::int32_t tool) {
    for (FlagHit& f : b.flags)
        if (f.flag == flag) {
            if (value < f.value) f = {flag, t_s, value, tool};
            return;
        }
    b.flags.push_back({flag, t_s, value, tool});
}

}  // namespace

std::string block_name(const std::vector<std::string>& block_names, std::int32_t block) {
    return block >= 0 && std::size_t(block) < block_names.size() ? block_names[std::size_t(block)] : "(none)";
}

BlockAccumulator::BlockAccumulator(std::string name, double t_s) {
    b_.block = std::move(name);
    b_.t_start_s = b_.t_end_s = t_s;
}

void BlockAccumulator::add_motion(double t_s) {
    b_.t_start_s = std::min(b_.t_start_s, t_s);
    b_.t_end_s = std::max(b_.t_end_s, t_s);
}

void BlockAccumulator::add_row(const ForceSample& s, const RowExtra& x, const std::vector<Limits>& slot_limits) {
    BlockSummary& b = b_;
    b.tool = s.tool;   // the tool in the spindle at the block's end, unless one cut in it
    const double force = std::sqrt(double(s.fx_N) * s.fx_N + double(s.fy_N) * s.fy_N + double(s.fz_N) * s.fz_N);
    b.peak_force_N = std::max(b.peak_force_N, force);
    b.peak_torque_Nm = std::max(b.peak_torque_Nm, double(s.torque_Nm));
    b.peak_power_kW = std::max(b.peak_power_kW, double(s.power_kW));
    b.max_chip_mm = std::max(b.max_chip_mm, double(s.chip_mm));
    b.max_bending_MPa = std::max(b.max_bending_MPa, double(s.bending_MPa));
    b.max_radial_engagement_mm = std::max(b.max_radial_engagement_mm, double(s.radial_engagement_mm));
    b.max_axial_engagement_mm = std::max(b.max_axial_engagement_mm, double(s.axial_engagement_mm));
    b.removed_mm3 += s.removed_mm3;
    if (x.engaged > 0) {
        force_sum_N_ += force;
        ++cutting_rows_;
        auto it = std::find_if(tools_.begin(), tools_.end(), [&](const ToolCount& c) { return c.tool == s.tool; });
        if (it == tools_.end()) tools_.push_back({s.tool, 1});
        else ++it->rows;
    }
    if (x.slot < 0 || std::size_t(x.slot) >= slot_limits.size()) {
        trip(b, "unknown_tool", s.t_s, s.tool, s.tool);
        return;
    }
    const Limits& limits = slot_limits[std::size_t(x.slot)];
    const std::int32_t t = s.tool;
    if (limits.force_N > 0 && force > limits.force_N) trip(b, "force_limit", s.t_s, force, t);
    if (limits.torque_Nm > 0 && s.torque_Nm > limits.torque_Nm) trip(b, "torque_limit", s.t_s, s.torque_Nm, t);
    if (limits.power_kW > 0 && s.power_kW > limits.power_kW) trip(b, "power_limit", s.t_s, s.power_kW, t);
    if (limits.chip_mm > 0 && s.chip_mm > limits.chip_mm) trip(b, "chip_load_limit", s.t_s, s.chip_mm, t);
    if (limits.bending_MPa > 0 && s.bending_MPa > limits.bending_MPa) trip(b, "bending_limit", s.t_s, s.bending_MPa, t);
    if (limits.rapid_feed_mm_min > 0 && x.feed_mm_min >= limits.rapid_feed_mm_min && (x.engaged > 0 || s.removed_mm3 > 0))
        trip(b, "rapid_in_material", s.t_s, x.feed_mm_min, t);
    if (s.holder_contact) trip(b, "holder_contact", s.t_s, 1.0, t);
    else if (limits.holder_clearance_mm > 0 && x.holder_clearance_mm < limits.holder_clearance_mm)
        nearest(b, "holder_near_miss", s.t_s, x.holder_clearance_mm, t);
    if (x.stopped_in_material) trip(b, "spindle_stopped", s.t_s, x.spindle_rpm, t);
}

BlockSummary BlockAccumulator::summary() const {
    BlockSummary b = b_;
    if (cutting_rows_ > 0) b.mean_force_N = force_sum_N_ / double(cutting_rows_);
    if (!tools_.empty())
        b.tool = std::max_element(tools_.begin(), tools_.end(), [](const ToolCount& a, const ToolCount& c) {
                     return a.rows < c.rows;
                 })->tool;
    return b;
}

BlockSummaries::BlockSummaries(const motion_io::MotionModel& motion, std::vector<Limits> limits,
                               const TimeWindow* window)
    : block_names_(motion.block_names), limits_(std::move(limits)) {
    std::int32_t max_block = -1;
    for (std::int32_t b : motion.block) max_block = std::max(max_block, b);
    index_.assign(std::size_t(max_block) + 2, -1);
    for (std::size_t i = 0; i < motion.size(); ++i)
        if (!window || (motion.t_s[i] >= window->from_s && motion.t_s[i] < window->to_s))
            at(motion.block[i], motion.t_s[i]).add_motion(motion.t_s[i]);
}

BlockAccumulator& BlockSummaries::at(std::int32_t block, double t_s) {
    const std::size_t slot = std::size_t(std::max(block, std::int32_t(-1)) + 1);
    if (slot >= index_.size()) index_.resize(slot + 1, -1);
    std::ptrdiff_t& k = index_[slot];
    if (k < 0) {
        k = std::ptrdiff_t(acc_.size());
        acc_.emplace_back(block_name(block_names_, block), t_s);
    }
    return acc_[std::size_t(k)];
}

void BlockSummaries::add_rows(const ForceSample* rows, const RowExtra* extra, std::size_t n) {
    for (std::size_t r = 0; r < n; ++r) at(rows[r].block, rows[r].t_s).add_row(rows[r], extra[r], limits_);
}

std::vector<BlockSummary> BlockSummaries::result() const {
    std::vector<BlockSummary> out;
    out.reserve(acc_.size());
    for (const BlockAccumulator& a : acc_) out.push_back(a.summary());
    return out;
}

std::vector<BlockSummary> summarise_blocks(const motion_io::MotionModel& motion, const std::vector<ForceSample>& rows,
                                           const std::vector<RowExtra>& extra, const std::vector<Limits>& slot_limits) {
    BlockSummaries s(motion, slot_limits);
    s.add_rows(rows.data(), extra.data(), rows.size());
    return s.result();
}

void check_finite_summaries(const Prediction& p) {
    for (const BlockSummary& b : p.blocks)
        for (const double v : {b.t_start_s, b.t_end_s, b.peak_force_N, b.mean_force_N, b.peak_torque_Nm, b.peak_power_kW,
                               b.max_chip_mm, b.max_bending_MPa, b.max_radial_engagement_mm, b.max_axial_engagement_mm,
                               b.removed_mm3})
            if (!std::isfinite(v))
                throw std::runtime_error("predict: the engine computed a non-finite summary for block " + b.block +
                                         "; nothing is written");
    for (const BlockSummary& b : p.blocks)
        for (const FlagHit& f : b.flags)
            if (!std::isfinite(f.value) || !std::isfinite(f.t_s))
                throw std::runtime_error("predict: the engine computed a non-finite summary for block " + b.block +
                                         "; nothing is written");
}

}  // namespace cutload::force_model
