// StreamingPrediction: the engine driver (engine/driver.hpp) over a motion model that grows. Rows
// are taken out as they become final so memory stays bounded by the motion grid (about 100 bytes
// a sample) rather than by the rows (one per angle step); at the WholeLog pace the walked motion
// is dropped too. Each block's summary is accumulated row by row across batches by the
// BlockAccumulator that predict()'s BlockSummaries use, and handed out when the block has ended,
// so it equals the offline summary.
#include "force_model/streaming.hpp"
#include "cutters/cutter.hpp"
#include "engine/block_summary.hpp"
#include "engine/driver.hpp"
#include "engine/motion_walk.hpp"
#include "engine/rows.hpp"
#include "engine/setup.hpp"
#include "engine/tool_plan.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <optional>
#include <stdexcept>
#include <string>

namespace cutload::force_model {

struct StreamingPrediction::Impl {
    RunSpec spec;
    PredictOptions opt;
    StreamPace pace;
    EngineSettings settings;
    EnginePhases phases;
    motion_io::MotionModel motion;
    ToolPlan plan;   // grows with the motion (ToolPlan::append)
    std::vector<Limits> slot_limits;
    std::unique_ptr<EngineSetup> setup;
    std::unique_ptr<Engine> engine;   // at the WholeLog pace made with the first walk (below)
    std::size_t walked = 0;          // samples whose interval to the next has been walked (next to walk from)
    std::size_t session_begin = 0;
    std::size_t added = 0;           // samples added in all
    // Every block's summary so far, by block index + 1 (0: rows without a block), accumulated
    // across batches; `order` is the order of first appearance, `open` the blocks with motion or
    // rows not yet handed out.
    std::vector<std::optional<BlockAccumulator>> acc;
    std::vector<std::size_t> order;
    std::vector<bool> open;
    std::size_t cutting_steps = 0;
    double last_row_t_s = 0;
    bool have_row = false;
    // simulated_seconds() of the motion, session by session, without holding it.
    double simulated_s = 0, session_t0_s = 0, last_t_s = 0;
    std::size_t session_samples = 0;
    // WholeLog without rows_out: the rows the engine handed out since the last call (a session
    // that ends inside add() hands out its rows then), moved to the next call's StreamOutput.
    std::vector<ForceSample> held_rows;
    std::chrono::steady_clock::time_point wall0 = std::chrono::steady_clock::now();

    Impl(const RunSpec& s, const PredictOptions& o, StreamPace p) : spec(s), opt(o), pace(p) {
        opt.progress = nullptr;
        if (pace == StreamPace::Live) {
            // The live run hands out its own rows (take_rows) and writes no checkpoints.
            opt.rows_out = nullptr;
            opt.checkpoint = nullptr;
        }
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
        // predict() makes its engine knowing the first sample's tool; the whole log's pace waits
        // for it too, so the engine starts as predict()'s does.
        if (pace == StreamPace::Live) engine = std::make_unique<Engine>(motion, spec, plan, opt, settings, *setup, phases);
        motion.session_start.push_back(0);
    }

    Engine& the_engine() {
        if (engine) return *engine;
        engine = std::make_unique<Engine>(motion, spec, plan, opt, settings, *setup, phases);
        engine->take_rows_as_they_come([this](const RowTable& rows, std::size_t n) { take_from_engine(rows, n); });
        if (opt.checkpoint && !motion.t_s.empty()) engine->write_checkpoints_from(motion.t_s.front());
        return *engine;
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

    void count_row(const ForceSample& s, const RowExtra& x) {
        block_at(s.block, s.t_s).add_row(s, x, slot_limits);
        cutting_steps += x.engaged > 0 ? 1 : 0;
        last_row_t_s = s.t_s;
        have_row = true;
    }

    // Live: the rows final so far, taken from the engine's table (all but the last one unless `all`).
    void take_rows(StreamOutput& out, bool all) {
        RowTable& rows = engine->rows();
        const std::size_t n = rows.size();
        const std::size_t keep = all ? 0 : std::min<std::size_t>(n, 1);
        const std::size_t take = n - keep;
        for (std::size_t r = 0; r < take; ++r) {
            out.samples.push_back(rows.samples[r]);
            count_row(rows.samples[r], rows.extra[r]);
        }
        rows.samples.erase(rows.samples.begin(), rows.samples.begin() + std::ptrdiff_t(take));
        rows.extra.erase(rows.extra.begin(), rows.extra.begin() + std::ptrdiff_t(take));
    }

    // WholeLog: the engine hands its rows out as predict() with rows_out has them.
    void take_from_engine(const RowTable& rows, std::size_t n) {
        const std::span<const ForceSample> piece(rows.samples.data(), n);
        check_finite_rows(piece);
        for (std::size_t r = 0; r < n; ++r) count_row(rows.samples[r], rows.extra[r]);
        if (opt.rows_out) opt.rows_out(piece);
        else held_rows.insert(held_rows.end(), piece.begin(), piece.end());
    }

    void give_held_rows(StreamOutput& out) {
        out.samples.insert(out.samples.end(), held_rows.begin(), held_rows.end());
        held_rows.clear();
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

    // Walks every interval added (`lag` = 0), or all but the last `lag` (the whole log's pace: a
    // checkpoint is never due at the last sample of a log, and the sample added last may not be).
    void walk_new(std::size_t lag = 0) {
        const std::size_t n = motion.size() >= lag ? motion.size() - lag : 0;
        if (n > walked + 1) {
            the_engine().walk(walked, n);
            walked = n - 1;
        }
    }

    // WholeLog: the samples before the next interval to walk are not read again.
    void forget_walked() {
        const std::size_t k = walked;
        if (k == 0) return;
        for (auto* v : {&motion.t_s, &motion.x_mm, &motion.y_mm, &motion.z_mm, &motion.vx_mm_s, &motion.vy_mm_s,
                        &motion.vz_mm_s, &motion.spindle_rpm, &motion.spindle_angle_deg})
            v->erase(v->begin(), v->begin() + std::ptrdiff_t(k));
        motion.block.erase(motion.block.begin(), motion.block.begin() + std::ptrdiff_t(k));
        motion.tool.erase(motion.tool.begin(), motion.tool.begin() + std::ptrdiff_t(k));
        plan.forget_front(k);
        the_engine().forget_samples(k);
        walked -= k;
        session_begin -= std::min(k, session_begin);
        motion.session_start.assign(1, 0);
    }

    void end_of_session() {
        if (session_samples >= 2) simulated_s += last_t_s - session_t0_s;
        session_samples = 0;
    }
};

StreamingPrediction::StreamingPrediction(const RunSpec& spec, const PredictOptions& opt, StreamPace pace)
    : impl_(std::make_unique<Impl>(spec, opt, pace)) {}

StreamingPrediction::~StreamingPrediction() = default;

std::size_t StreamingPrediction::motion_samples() const { return impl_->added; }
const motion_io::MotionModel& StreamingPrediction::motion() const { return impl_->motion; }

void StreamingPrediction::begin_session() {
    Impl& m = *impl_;
    if (m.motion.size() == m.session_begin) return;   // nothing in the current one yet
    if (m.pace == StreamPace::WholeLog && m.opt.checkpoint)
        throw std::logic_error("streaming: checkpoints are written for a log of one session");
    m.walk_new();
    m.the_engine().end_session();
    m.end_of_session();
    m.session_begin = m.motion.size();
    m.walked = m.session_begin;
    m.motion.session_start.push_back(m.session_begin);
}

void StreamingPrediction::add(const motion_io::MotionState& s, const std::vector<std::string>& block_names) {
    Impl& m = *impl_;
    motion_io::MotionModel& mm = m.motion;
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
    m.plan.append(s.tool);
    m.block_at(s.block, s.t_s).add_motion(s.t_s);
    if (m.session_samples++ == 0) m.session_t0_s = s.t_s;
    m.last_t_s = s.t_s;
    ++m.added;
}

void StreamingPrediction::add(const motion_io::MotionModel& piece) { add(piece, 0, piece.size()); }

void StreamingPrediction::add(const motion_io::MotionModel& piece, std::size_t begin, std::size_t end) {
    Impl& m = *impl_;
    if (m.motion.block_names.size() != piece.block_names.size()) m.motion.block_names = piece.block_names;
    auto next_session = std::size_t(std::lower_bound(piece.session_start.begin(), piece.session_start.end(), begin) -
                                    piece.session_start.begin());
    motion_io::MotionState s;
    for (std::size_t i = begin; i < std::min(end, piece.size()); ++i) {
        if (next_session < piece.session_start.size() && piece.session_start[next_session] == i) {
            begin_session();
            ++next_session;
        }
        s.t_s = piece.t_s[i];
        s.pos_mm[0] = piece.x_mm[i], s.pos_mm[1] = piece.y_mm[i], s.pos_mm[2] = piece.z_mm[i];
        s.vel_mm_s[0] = piece.vx_mm_s[i], s.vel_mm_s[1] = piece.vy_mm_s[i], s.vel_mm_s[2] = piece.vz_mm_s[i];
        s.spindle_rpm = piece.spindle_rpm[i];
        s.spindle_angle_deg = piece.spindle_angle_deg[i];
        s.block = piece.block[i];
        s.tool = piece.tool.empty() ? -1 : piece.tool[i];
        add(s, piece.block_names);
    }
    // The grid's own step, not one rounded from two times.
    m.motion.step_s = piece.step_s;
}

void StreamingPrediction::advance(StreamOutput& out) {
    Impl& m = *impl_;
    if (m.opt.cancel && m.opt.cancel->load()) throw Cancelled();
    if (m.pace == StreamPace::WholeLog) {
        m.walk_new(2);
        m.give_held_rows(out);
        m.hand_out(out, false);
        m.forget_walked();
        return;
    }
    m.walk_new();
    m.engine->settle();
    m.take_rows(out, false);
    m.hand_out(out, false);
}

Prediction StreamingPrediction::finish(StreamOutput& out) {
    Impl& m = *impl_;
    m.walk_new();
    Prediction p;
    if (m.added > 0 || m.pace == StreamPace::Live) {
        Engine& engine = m.the_engine();
        engine.end_session();
        if (m.pace == StreamPace::WholeLog) engine.drain_rows();
        else m.take_rows(out, true);
        p.stats.steps = engine.steps();
    }
    m.give_held_rows(out);
    m.end_of_session();
    m.hand_out(out, true);
    const bool keep_stock = m.pace == StreamPace::Live || m.opt.keep_final_stock;
    if (keep_stock) m.setup->backend->download(*m.setup->stock);
    p.block_names = m.motion.block_names;
    for (std::size_t k : m.order) p.blocks.push_back(m.acc[k]->summary());
    if (keep_stock) p.final_stock = std::move(m.setup->stock);
    p.stats.simulated_s = m.simulated_s;
    p.stats.cutting_steps = m.cutting_steps;
    p.stats.unknown_tool_samples = m.plan.unknown_samples;
    p.stats.unknown_tools = m.plan.unknown_tools;
    p.stats.device = m.setup->backend->name();
    p.stats.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - m.wall0).count();
    m.setup->backend.reset();
    check_finite_summaries(p);
    return p;
}

}  // namespace cutload::force_model
