#include "engine/block_summary.hpp"

#include <algorithm>
#include <cmath>

namespace cutload::force_model {

namespace {

void trip(BlockSummary& b, const char* flag, double t_s, double value, std::int32_t tool) {
    for (const FlagHit& f : b.flags)
        if (f.flag == flag) return;   // keep the first time it tripped
    b.flags.push_back({flag, t_s, value, tool});
}

// Cutting rows per T number in one block (a block rarely sees more than one tool).
struct ToolCount {
    std::int32_t tool;
    std::size_t rows;
};

void count_tool(std::vector<ToolCount>& counts, std::int32_t tool) {
    for (ToolCount& c : counts)
        if (c.tool == tool) {
            ++c.rows;
            return;
        }
    counts.push_back({tool, 1});
}

}  // namespace

std::vector<BlockSummary> summarise_blocks(const motion_io::MotionModel& motion, const std::vector<ForceSample>& rows,
                                           const std::vector<RowExtra>& extra, const std::vector<Limits>& slot_limits) {
    // One summary per block in order of first appearance in the motion; rows without a block
    // (a negative index) are summarised as "(none)". Block indices are small: a flat table maps
    // them to summaries.
    std::vector<BlockSummary> out;
    std::int32_t max_block = -1;
    for (std::int32_t b : motion.block) max_block = std::max(max_block, b);
    for (const ForceSample& s : rows) max_block = std::max(max_block, s.block);
    std::vector<std::ptrdiff_t> index(std::size_t(max_block) + 2, -1);
    auto slot_index = [&](std::int32_t block, double t_s) -> std::size_t {
        std::ptrdiff_t& at = index[std::size_t(std::max(block, std::int32_t(-1)) + 1)];
        if (at < 0) {
            at = std::ptrdiff_t(out.size());
            BlockSummary b;
            b.block = block >= 0 && std::size_t(block) < motion.block_names.size() ? motion.block_names[block] : "(none)";
            b.t_start_s = b.t_end_s = t_s;
            out.push_back(std::move(b));
        }
        return std::size_t(at);
    };
    for (std::size_t i = 0; i < motion.size(); ++i) {
        BlockSummary& b = out[slot_index(motion.block[i], motion.t_s[i])];
        b.t_start_s = std::min(b.t_start_s, motion.t_s[i]);
        b.t_end_s = std::max(b.t_end_s, motion.t_s[i]);
    }
    std::vector<double> force_sum(out.size() + 1, 0.0);
    std::vector<std::size_t> cutting_rows(out.size() + 1, 0);
    std::vector<std::vector<ToolCount>> tools(out.size() + 1);
    for (std::size_t r = 0; r < rows.size(); ++r) {
        const ForceSample& s = rows[r];
        const RowExtra& x = extra[r];
        const std::size_t bi = slot_index(s.block, s.t_s);
        BlockSummary& b = out[bi];
        if (force_sum.size() < out.size()) {
            force_sum.resize(out.size(), 0.0);
            cutting_rows.resize(out.size(), 0);
            tools.resize(out.size());
        }
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
            force_sum[bi] += force;
            ++cutting_rows[bi];
            count_tool(tools[bi], s.tool);
        }
        if (x.slot < 0 || std::size_t(x.slot) >= slot_limits.size()) {
            trip(b, "unknown_tool", s.t_s, s.tool, s.tool);
            continue;
        }
        const Limits& limits = slot_limits[std::size_t(x.slot)];
        const std::int32_t t = s.tool;
        if (limits.force_N > 0 && force > limits.force_N) trip(b, "force_limit", s.t_s, force, t);
        if (limits.torque_Nm > 0 && s.torque_Nm > limits.torque_Nm) trip(b, "torque_limit", s.t_s, s.torque_Nm, t);
        if (limits.power_kW > 0 && s.power_kW > limits.power_kW) trip(b, "power_limit", s.t_s, s.power_kW, t);
        if (limits.chip_mm > 0 && s.chip_mm > limits.chip_mm) trip(b, "chip_load_limit", s.t_s, s.chip_mm, t);
        if (limits.bending_MPa > 0 && s.bending_MPa > limits.bending_MPa)
            trip(b, "bending_limit", s.t_s, s.bending_MPa, t);
        if (limits.rapid_feed_mm_min > 0 && x.feed_mm_min >= limits.rapid_feed_mm_min && (x.engaged > 0 || s.removed_mm3 > 0))
            trip(b, "rapid_in_material", s.t_s, x.feed_mm_min, t);
        if (s.holder_contact) trip(b, "holder_contact", s.t_s, 1.0, t);
        if (x.stopped_in_material) trip(b, "spindle_stopped", s.t_s, x.spindle_rpm, t);
    }
    for (std::size_t bi = 0; bi < out.size(); ++bi) {
        if (bi < cutting_rows.size() && cutting_rows[bi] > 0) out[bi].mean_force_N = force_sum[bi] / double(cutting_rows[bi]);
        if (bi < tools.size() && !tools[bi].empty())
            out[bi].tool = std::max_element(tools[bi].begin(), tools[bi].end(), [](const ToolCount& a, const ToolCount& b) {
                               return a.rows < b.rows;
                           })->tool;
    }
    return out;
}

}  // namespace cutload::force_model
