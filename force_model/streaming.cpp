// StreamingPrediction: the engine driver (engine/driver.hpp) over a motion model that grows. Rows
// are taken out as they become final so memory stays bounded by the motion grid (about 100 bytes
// a sample) rather than by the rows (one per angle step). Each block's summary is accumulated
// row by row across batches by the BlockAccumulator that predict()'s BlockSummaries use, and
// handed out when the block has ended, so it equals the offline summary.
#include "force_model/streaming.hpp"
#include "cutters/cutter.hpp"
#include "engine/block_summary.hpp"
#include "engine/driver.hpp"
#include "engine/motion_walk.hpp"
#include "engine/setup.hpp"
#include "engine/tool_plan.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <optional>
#include <string>

namespace cutload::force_model {

struct StreamingPrediction::Impl {
    RunSpec spec;
    PredictOptions opt;
    EngineSettings settings;
    EnginePhases phases;
    motion_io::MotionModel motion;
    ToolPlan plan;   // grows with the motion (ToolPlan::append)
    std::vector<Limits> slot_limits;
    std::unique_ptr<EngineSetup> setup;
    std::unique_ptr<Engine> engine;
    std::size_t walked = 0;          // samples whose interval to the next has been walked (next to walk from)
    std::size_t session_begin = 0;
    // Every block's summary so far, by block index + 1 (0: rows without a block), accumulated
    // across batches; `order` is the order of first appearance, `open` the blocks with motion or
    // rows not yet handed out.
    std::vector<std::optional<BlockAccumulator>> acc;
    std::vector<std::size_t> order;
    std::vector<bool> open;
    std::size_t cutting_steps = 0;
    double last_row_t_s = 0;
    bool have_row = false;
    std::chrono::steady_clock::time_point wall0 = std::chrono::steady_clock::now();

    Impl(const RunSpec& s, const PredictOptions& o) : spec(s), opt(o) {
        opt.progress = nullptr;
        if (!(spec.resolution.angle_step_deg > 0) || !(spec.resolution.axial_step_mm > 0) || !(spec.resolution.grid_mm > 0))
            throw SpecError("resolution: steps must be > 0");
        plan = plan_tools(motion, spec);
        for (const PlannedTool& t : plan.tools) {
            if (t.cutter.flutes < 1)
                throw SpecError(t.number < 0 ? std::string("tool.flutes: must be >= 1")
                                             : "tool T" + std::to_string(t.number) + ": flutes must be >= 1");
            slot_limits.push_back(t.limits);
        }
        setup = std::make_unique<EngineSetup>(spec, plan, opt, settings);
        engine = std::make_unique<Engine>(motion, spec, plan, opt, settings, *setup, phases);
        motion.session_start.push_back(0);
    }

    BlockAccumulator& block_at(std::int32_t block, double t_s) {
        const std::size_t k = std::size_t(std::max(block, std::int32_t(-1)) + 1);
        if (acc.size() <= k) {
            acc.resize(k + 1);
            open.resize(k + 1, false);
        }
        if (!acc[k]) {
            acc[k].emplace(block_name(motion.block_names, block), t_s);
            order.push_back(k);
        }
        open[k] = true;
        return *acc[k];
    }

    void take_rows(StreamOutput& out, bool all) {
        RowTable& rows = engine->rows();
        const std::size_t n = rows.size();
        const std::size_t keep = all ? 0 : std::min<std::size_t>(n, 1);
        const std::size_t take = n - keep;
        for (std::size_t r = 0; r < take; ++r) {
            out.samples.push_back(rows.samples[r]);
            block_at(rows.samples[r].block, rows.samples[r].t_s).add_row(rows.samples[r], rows.extra[r], slot_limits);
            cutting_steps += rows.extra[r].engaged > 0 ? 1 : 0;
            last_row_t_s = rows.samples[r].t_s;
            have_row = true;
        }
        rows.samples.erase(rows.samples.begin(), rows.samples.begin() + std::ptrdiff_t(take));
        rows.extra.erase(rows.extra.begin(), rows.extra.begin() + std::ptrdiff_t(take));
    }

    // Hands out the summary of every open block whose rows have all been taken (all of them when
    // `all`). Rows come in time order and a row belongs to the block of the nearer of its
    // interval's two samples, so a block's last row lies within half a grid step after its last
    // sample: a row taken past that closes it. A block that runs again later is handed out again,
    // its summary then covering all its stretches (as predict() has it).
    void hand_out(StreamOutput& out, bool all) {
        for (std::size_t k : order) {
            if (!open[k]) continue;
            if (!all && !(have_row && last_row_t_s > acc[k]->t_end_s() + 0.5 * motion.step_s + 1e-9)) continue;
            out.blocks.push_back(acc[k]->summary());
            open[k] = false;
        }
    }

    void walk_new() {
        const std::size_t n = motion.size();
        if (n > walked + 1) {
            engine->walk(walked, n);
            walked = n - 1;
        }
    }
};

StreamingPrediction::StreamingPrediction(const RunSpec& spec, const PredictOptions& opt)
    : impl_(std::make_unique<Impl>(spec, opt)) {}

StreamingPrediction::~StreamingPrediction() = default;

std::size_t StreamingPrediction::motion_samples() const { return impl_->motion.size(); }
const motion_io::MotionModel& StreamingPrediction::motion() const { return impl_->motion; }

void StreamingPrediction::begin_session() {
    Impl& m = *impl_;
    if (m.motion.size() == m.session_begin) return;   // nothing in the current one yet
    m.walk_new();
    m.engine->end_session();
    m.session_begin = m.motion.size();
    m.walked = m.session_begin;
    m.motion.session_start.push_back(m.session_begin);
}

void StreamingPrediction::add(const motion_io::MotionState& s, const std::vector<std::string>& block_names) {
    motion_io::MotionModel& mm = impl_->motion;
    if (mm.block_names.size() != block_names.size()) mm.block_names = block_names;
    mm.t_s.push_back(s.t_s);
    mm.x_mm.push_back(s.pos_mm[0]);
    mm.y_mm.push_back(s.pos_mm[1]);
    mm.z_mm.push_back(s.pos_mm[2]);
    mm.vx_mm_s.push_back(s.vel_mm_s[0]);
    mm.vy_mm_s.push_back(s.vel_mm_s[1]);
    mm.vz_mm_s.push_back(s.vel_mm_s[2]);
    mm.spindle_rpm.push_back(s.spindle_rpm);
    mm.spindle_angle_deg.push_back(s.spindle_angle_deg);
    mm.block.push_back(s.block);
    mm.tool.push_back(s.tool);
    mm.step_s = mm.size() >= 2 ? mm.t_s[mm.size() - 1] - mm.t_s[mm.size() - 2] : mm.step_s;
    impl_->plan.append(s.tool);
    impl_->block_at(s.block, s.t_s).add_motion(s.t_s);
}

void StreamingPrediction::advance(StreamOutput& out) {
    Impl& m = *impl_;
    if (m.opt.cancel && m.opt.cancel->load()) throw Cancelled();
    m.walk_new();
    m.engine->settle();
    m.take_rows(out, false);
    m.hand_out(out, false);
}

Prediction StreamingPrediction::finish(StreamOutput& out) {
    Impl& m = *impl_;
    m.walk_new();
    m.engine->end_session();
    m.take_rows(out, true);
    m.hand_out(out, true);
    m.setup->backend->download(*m.setup->stock);
    Prediction p;
    p.block_names = m.motion.block_names;
    for (std::size_t k : m.order) p.blocks.push_back(m.acc[k]->summary());
    p.final_stock = std::move(m.setup->stock);
    p.stats.simulated_s = simulated_seconds(m.motion);
    p.stats.steps = m.engine->steps();
    p.stats.cutting_steps = m.cutting_steps;
    p.stats.unknown_tool_samples = m.plan.unknown_samples;
    p.stats.unknown_tools = m.plan.unknown_tools;
    p.stats.device = m.setup->backend->name();
    p.stats.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - m.wall0).count();
    m.setup->backend.reset();
    return p;
}

}  // namespace cutload::force_model
