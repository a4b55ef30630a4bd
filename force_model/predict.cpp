// predict(): checks the inputs, plans which cutter cuts each sample (engine/tool_plan.hpp), sets up
// the engine (every cutter's tables, cutting law, stock, backend),
// runs its walk (engine/driver.hpp) and collects the rows, block summaries and final stock. See
// docs/force_model.md.
#include "engine.hpp"
#include "cutters/cutter.hpp"
#include "engine/block_summary.hpp"
#include "engine/driver.hpp"
#include "engine/motion_walk.hpp"
#include "engine/phase_timer.hpp"
#include "engine/setup.hpp"
#include "engine/tool_plan.hpp"
#include "engine/turning_run.hpp"
#include "kernels/tri_dexel.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>

namespace cutload::force_model {

namespace {

static_assert(EngineSettings{}.wall_tolerance_mm == kernels::kSliverMm,
              "the default wall tolerance is the kernels' float round-off");

void check_inputs(const motion_io::MotionModel& m, const RunSpec& spec) {
    const std::size_t n = m.size();
    for (const auto* v : {&m.x_mm, &m.y_mm, &m.z_mm, &m.vx_mm_s, &m.vy_mm_s, &m.vz_mm_s, &m.spindle_rpm,
                          &m.spindle_angle_deg})
        if (v->size() != n) throw std::invalid_argument("predict: motion model channels have different lengths");
    if (m.block.size() != n) throw std::invalid_argument("predict: motion model block channel has a different length");
    if (!m.tool.empty() && m.tool.size() != n)
        throw std::invalid_argument("predict: motion model tool channel has a different length");
    // The readers and the validate stage drop every non-finite reading (issue 19); a model built
    // another way must not carry one into the engine, where one NaN spoils every row after it.
    for (std::size_t i = 0; i < n; ++i)
        for (const double v : {m.t_s[i], m.x_mm[i], m.y_mm[i], m.z_mm[i], m.vx_mm_s[i], m.vy_mm_s[i], m.vz_mm_s[i],
                               m.spindle_rpm[i], m.spindle_angle_deg[i]})
            if (!std::isfinite(v))
                throw std::invalid_argument("predict: motion model sample " + std::to_string(i) +
                                            " holds a non-finite value (NaN or infinity)");
    if (!(spec.resolution.angle_step_deg > 0) || !(spec.resolution.axial_step_mm > 0) || !(spec.resolution.grid_mm > 0))
        throw SpecError("resolution: steps must be > 0");
    for (std::size_t s = 0; s < m.session_start.size(); ++s) {
        const std::size_t i = m.session_start[s];
        if (i >= std::max<std::size_t>(n, 1) || (s > 0 && i <= m.session_start[s - 1]))
            throw std::invalid_argument("predict: motion model session_start[" + std::to_string(s) + "] = " +
                                        std::to_string(i) + " is out of order or past the " + std::to_string(n) +
                                        " samples");
    }
}

void check_plan(const ToolPlan& plan) {
    for (std::size_t k = 0; k < plan.tools.size(); ++k)
        if (plan.tools[k].cutter.flutes < 1) {
            const std::int32_t t = plan.tools[k].number;
            throw SpecError(t < 0 ? std::string("tool.flutes: must be >= 1") : fmt::format("tool T{}: flutes must be >= 1", t));
        }
}

void check_outputs(const Prediction& p) {
    check_finite_rows(p.samples);
    check_finite_summaries(p);
}

std::vector<Limits> slot_limits(const ToolPlan& plan) {
    std::vector<Limits> limits;
    for (const PlannedTool& t : plan.tools) limits.push_back(t.limits);
    return limits;
}

// The block summaries and counts of the rows as they become final. With PredictOptions::rows_out
// (or a window) the rows leave the engine then and only these stay.
struct RowsOut {
    BlockSummaries blocks;
    std::size_t cutting_steps = 0;
    std::vector<ForceSample> window_rows;   // PredictOptions::window without rows_out
    RowsOut(const motion_io::MotionModel& motion, const ToolPlan& plan, const TimeWindow* window)
        : blocks(motion, slot_limits(plan), window) {}
};

void check_window(const motion_io::MotionModel& m, const TimeWindow& w) {
    if (session_ranges(m).size() > 1)
        throw SpecError(fmt::format("window: the log has {} sessions (the control restarted or the clock jumped); a "
                                    "window is recomputed on a log of one session",
                                    session_ranges(m).size()));
    if (!(std::isfinite(w.from_s) && std::isfinite(w.to_s) && w.from_s < w.to_s))
        throw SpecError(fmt::format("window: from_s {} s must be below to_s {} s", w.from_s, w.to_s));
    if (w.to_s <= m.t_s.front() || w.from_s >= m.t_s.back())
        throw SpecError(fmt::format("window: {} .. {} s lies outside the log's motion, {:.6f} .. {:.6f} s", w.from_s, w.to_s,
                                    m.t_s.front(), m.t_s.back()));
}

void check_resume(const motion_io::MotionModel& m, const PredictOptions& opt) {
    const StockCheckpoint& c = *opt.resume;
    if (!opt.window) throw SpecError("resume: a checkpoint starts the walk of a window; no window was given");
    if (!opt.base_stock && !(opt.own_stock && *opt.own_stock))
        throw SpecError("resume: the checkpoint's stock was not given (base_stock)");
    if (c.sample + 1 >= m.size() || m.t_s[c.sample] != c.t_s)
        throw SpecError(fmt::format("resume: the checkpoint at sample {} (t = {:.6f} s) is not of this motion", c.sample,
                                    c.t_s));
    if (c.t_s > opt.window->from_s)
        throw SpecError(fmt::format("resume: the checkpoint at t = {:.6f} s lies after the window's start, {:.6f} s", c.t_s,
                                    opt.window->from_s));
}

// The rows [first, end) of n (in time order: one session) inside the window.
std::pair<std::size_t, std::size_t> rows_in_window(const ForceSample* rows, std::size_t n, const TimeWindow& w) {
    const auto before = [](const ForceSample& r, double t_s) { return r.t_s < t_s; };
    const std::size_t first = std::size_t(std::lower_bound(rows, rows + n, w.from_s, before) - rows);
    const std::size_t end = std::size_t(std::lower_bound(rows + first, rows + n, w.to_s, before) - rows);
    return {first, end};
}

Prediction collect(const motion_io::MotionModel& motion, const ToolPlan& plan, Engine& engine, EngineSetup& setup,
                   RowsOut& rows_out, bool rows_taken, bool keep_final_stock) {
    if (keep_final_stock) setup.backend->download(*setup.stock);
    Prediction p;
    p.block_names = motion.block_names;
    engine.drain_rows();
    p.blocks = rows_out.blocks.result();
    p.stats.cutting_steps = rows_out.cutting_steps;
    p.samples = rows_taken ? std::move(rows_out.window_rows) : std::move(engine.rows().samples);
    p.stats.unknown_tool_samples = plan.unknown_samples;
    p.stats.unknown_tools = plan.unknown_tools;
    if (keep_final_stock) p.final_stock = std::move(setup.stock);
    p.stats.simulated_s = simulated_seconds(motion);
    p.stats.steps = engine.steps();
    p.stats.device = setup.backend->name();
    setup.backend.reset();
    check_finite_summaries(p);
    return p;
}

// The inputs are checked.
Prediction run_prediction(const motion_io::MotionModel& motion, const RunSpec& spec, const ToolPlan& plan,
                          const PredictOptions& opt, const EngineSettings& settings, EnginePhases* phases_out) {
    check_plan(plan);
    if (opt.window) check_window(motion, *opt.window);
    if (opt.resume) check_resume(motion, opt);
    const auto wall0 = Clock::now();
    EnginePhases phases;
    Prediction p;
    // The finish phase ends after the engine and its set-up are gone: tearing them down is part of a
    // prediction's cost.
    std::optional<PhaseTimer> finish_timer;
    {
        std::optional<PhaseTimer> setup_timer(std::in_place, phases.setup_s);
        EngineSetup setup(spec, plan, opt, settings);
        Engine engine(motion, spec, plan, opt, settings, setup, phases);
        const TimeWindow* window = opt.window ? &*opt.window : nullptr;
        RowsOut rows_out(motion, plan, window);
        if (window) engine.limit_to(*window);
        if (opt.resume) engine.resume_at(*opt.resume);
        const bool rows_taken = opt.rows_out || window;
        if (!rows_taken) {
            engine.watch_rows_as_they_come([&](const RowTable& rows, std::size_t first, std::size_t end) {
                const std::span<const ForceSample> piece(rows.samples.data() + first, end - first);
                check_finite_rows(piece);
                rows_out.blocks.add_rows(piece.data(), rows.extra.data() + first, piece.size());
                for (std::size_t r = first; r < end; ++r) rows_out.cutting_steps += rows.extra[r].engaged > 0 ? 1 : 0;
            });
        } else {
            engine.take_rows_as_they_come([&](const RowTable& rows, std::size_t n) {
                const auto [first, end] = window ? rows_in_window(rows.samples.data(), n, *window)
                                                 : std::pair<std::size_t, std::size_t>{0, n};
                const std::span<const ForceSample> piece(rows.samples.data() + first, end - first);
                check_finite_rows(piece);
                rows_out.blocks.add_rows(piece.data(), rows.extra.data() + first, piece.size());
                for (std::size_t r = first; r < end; ++r) rows_out.cutting_steps += rows.extra[r].engaged > 0 ? 1 : 0;
                if (opt.rows_out) opt.rows_out(piece);
                else rows_out.window_rows.insert(rows_out.window_rows.end(), piece.begin(), piece.end());
            });
        }
        setup_timer.reset();
        {
            PhaseTimer timer(phases.walk_s);
            engine.run();
        }
        finish_timer.emplace(phases.finish_s);
        p = collect(motion, plan, engine, setup, rows_out, rows_taken, opt.keep_final_stock && !window);
        if (window)
            p.stats.simulated_s = std::min(window->to_s, motion.t_s.back()) - std::max(window->from_s, motion.t_s.front());
    }
    finish_timer.reset();
    // The walk's own share: what the timed phases inside it leave over (step generation, batching,
    // air checks).
    phases.walk_s -= phases.queue_s + phases.wait_s + phases.rows_s + phases.removal_s + phases.holder_s;
    p.stats.wall_s = std::chrono::duration<double>(Clock::now() - wall0).count();
    phases.total_s = p.stats.wall_s;
    if (phases_out) *phases_out = phases;
    if (opt.progress) opt.progress(1.0);
    return p;
}

}  // namespace

Prediction predict_with_cutter(const motion_io::MotionModel& motion, const RunSpec& spec, const Cutter& cutter,
                               const PredictOptions& opt, const EngineSettings& settings, EnginePhases* phases) {
    check_inputs(motion, spec);
    return run_prediction(motion, spec, single_cutter_plan(motion, cutter, spec.limits), opt, settings, phases);
}

Prediction predict_with(const motion_io::MotionModel& motion, const RunSpec& spec, const PredictOptions& opt,
                        const EngineSettings& settings, EnginePhases* phases) {
    check_inputs(motion, spec);
    return run_prediction(motion, spec, plan_tools(motion, spec), opt, settings, phases);
}

Prediction predict(const motion_io::MotionModel& motion, const RunSpec& spec, const PredictOptions& opt) {
    return predict_with(motion, spec, opt, EngineSettings{});
}

Prediction predict_turning(const motion_io::MotionModel& motion, const ToolPoses& poses, const RunSpec& spec,
                           const PredictOptions& opt) {
    check_inputs(motion, spec);
    if (opt.window) throw SpecError("window: a run whose tool turns as it cuts is not recomputed by window");
    const ToolPlan plan = plan_tools(motion, spec);
    check_plan(plan);
    Prediction p = run_turning(motion, poses, spec, plan, opt, check_finite_rows);
    check_outputs(p);
    return p;
}

double multi_direction_stock_bytes(const StockBox& box, double grid_mm) {
    const std::array<double, 3> lo{box.min_mm[0], box.min_mm[1], box.min_mm[2]}, hi{box.max_mm[0], box.max_mm[1], box.max_mm[2]};
    return double(kernels::tri_dexel_bytes(lo, hi, grid_mm)) + stock_cells(box, grid_mm) * double(stock_bytes_per_cell());
}

double multi_direction_stock_rays(const StockBox& box, double grid_mm) {
    const std::array<double, 3> lo{box.min_mm[0], box.min_mm[1], box.min_mm[2]}, hi{box.max_mm[0], box.max_mm[1], box.max_mm[2]};
    return double(kernels::tri_dexel_bytes(lo, hi, grid_mm)) / double(kernels::kDexelFloats * sizeof(float));
}

}  // namespace cutload::force_model
