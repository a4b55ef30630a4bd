#include "app/program_run.hpp"
#include "app/workpiece_motion.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <map>
#include <stdexcept>
#include <set>

namespace cutload::app {
namespace {

// The log names blocks, and (nearly) all of them are the program's.
bool log_blocks_match(const motion_io::MotionModel& m, const motion_io::NcProgram& p) {
    const std::vector<std::string> names = motion_io::program_block_names(p);
    const std::set<std::string> known(names.begin(), names.end());
    std::size_t named = 0, matching = 0;
    for (std::int32_t b : m.block) {
        if (b < 0) continue;
        ++named;
        if (known.count(m.block_names[static_cast<std::size_t>(b)])) ++matching;
    }
    return named > 0 && matching >= 0.95 * double(named);
}

bool names_tools(const motion_io::MotionModel& m) {
    return std::any_of(m.tool.begin(), m.tool.end(), [](std::int32_t t) { return t >= 0; });
}

}  // namespace

std::vector<std::int32_t> program_tools_per_sample(const motion_io::NcProgram& program,
                                                   const motion_io::BlockMapping& mapping,
                                                   const motion_io::MotionModel& motion) {
    const std::size_t n = motion.size();
    std::vector<std::int32_t> tool(n, -1);
    // Per block name: its one tool, -2 when blocks of that name run with different tools.
    std::map<std::string, std::int32_t> by_name;
    for (const motion_io::NcBlock& b : program.blocks) {
        if (b.tool < 0) continue;
        auto [it, fresh] = by_name.try_emplace(b.name, b.tool);
        if (!fresh && it->second != b.tool) it->second = -2;
    }
    if (by_name.empty()) return tool;
    std::vector<std::int32_t> of_block(motion.block_names.size(), -1);
    for (std::size_t k = 0; k < motion.block_names.size(); ++k)
        if (const auto it = by_name.find(motion.block_names[k]); it != by_name.end()) of_block[k] = it->second;
    for (std::size_t i = 0; i < n; ++i) {
        const std::int32_t b = motion.block[i];
        std::int32_t t = b >= 0 && std::size_t(b) < of_block.size() ? of_block[std::size_t(b)] : -1;
        if (t == -2) {
            const std::int32_t pb = i < mapping.program_block.size() ? mapping.program_block[i] : -1;
            t = pb >= 0 ? program.blocks[std::size_t(pb)].tool : -1;
        }
        tool[i] = t;
    }
    std::int32_t held = -1;
    for (std::int32_t& t : tool) {
        if (t >= 0) held = t;
        else t = held;
    }
    const auto first = std::find_if(tool.begin(), tool.end(), [](std::int32_t t) { return t >= 0; });
    if (first != tool.end()) std::fill(tool.begin(), first, *first);
    return tool;
}

std::optional<std::array<double, 3>> log_start_mm(const motion_io::MotionModel& motion) {
    if (motion.x_mm.empty()) return std::nullopt;
    return std::array<double, 3>{motion.x_mm.front(), motion.y_mm.front(), motion.z_mm.front()};
}

motion_io::NcReadOptions program_read_options(const ProgramSettings& settings, const RunSpec& spec,
                                              std::optional<std::array<double, 3>> start_mm) {
    motion_io::NcReadOptions ro;
    ro.work_offsets_mm = motion_io::default_work_offsets(spec.offset_mm);
    for (const auto& [name, v] : settings.work_offsets_mm) ro.work_offsets_mm[name] = v;
    ro.ignore_words = settings.ignore_words;
    ro.decimal_less_is_increment = settings.decimal_less_is_increment;
    ro.arc_centers = settings.arc_centers;
    ro.program_units = settings.program_units;
    ro.rotary_axes = settings.rotary_axes;
    ro.rotary_feed = settings.rotary_feed;
    ro.start_deg = settings.start_deg;
    ro.tool_centre_point = settings.tool_centre_point;
    ro.arc_tolerance_mm = settings.arc_tolerance_mm;
    ro.tool_change_on_t = settings.tool_change_on_t;
    ro.block_skip = settings.block_skip;
    ro.rapid_mm_min = settings.rapid_mm_min;
    ro.limits = settings.limits;
    ro.start_mm = start_mm;
    return ro;
}

ProgramRun prepare_program_run(motion_io::NcProgram program, const ProgramSettings& settings,
                               motion_io::MotionModel& motion, const Control& control) {
    if (motion.size() < 2) throw motion_io::IngestError("the log holds fewer than two motion samples");
    ProgramRun run;
    run.program = std::move(program);
    run.commanded.step_s = motion.step_s;
    run.commanded.rapid_mm_min = settings.rapid_mm_min;
    run.commanded.max_samples = settings.limits.max_samples;
    if (!(settings.min_match >= 0 && settings.min_match <= 1))
        throw std::invalid_argument(fmt::format("min_match {} is outside 0..1", settings.min_match));
    // The reader counted samples at the default step; the log's own step decides.
    if (const double n = motion_io::commanded_sample_count(run.program, run.commanded); n > settings.limits.max_samples)
        throw motion_io::NcProgramError(fmt::format("{}: the commanded motion would take {:.4g} samples at the log's {:g} ms step, above the limit of {:.4g}",
                                                    run.program.file, n, motion.step_s * 1e3, settings.limits.max_samples));

    motion_io::BlockMappingOptions mo;
    mo.lead_s = settings.block_lead_ms * 1e-3;
    mo.rapid_mm_min = settings.rapid_mm_min;
    mo.cancel = control.cancel;
    run.mapped = settings.map_blocks || !log_blocks_match(motion, run.program);
    try {
        if (!run.mapped) {
            // Deviations do not depend on the lead; the agreement is reported at the calibrated one.
            run.estimated_lead_s = motion_io::estimate_block_lead_s(motion, run.program, mo);
            mo.lead_s = *run.estimated_lead_s;
        }
        run.mapping = motion_io::map_blocks(motion, run.program, mo);
    } catch (const motion_io::MappingCancelled&) {
        throw force_model::Cancelled();   // one cancel for every phase of a use case
    }
    // The program starts where the log does, so its first move always meets the log; a log that
    // mostly runs elsewhere is another program, or this one under another work offset. Blocks and
    // comparisons taken from it would be wrong without a sign, so it is refused.
    const auto& q = run.mapping.quality;
    if (q.counted_matched_fraction < settings.min_match) {
        const double n = q.samples ? double(q.samples) : 1.0;
        throw motion_io::NcProgramError(fmt::format(
            "{}: only {:.1f} % of the log's counted samples lie within {} mm of the program's path (at least {:.0f} % must; "
            "{:.1f} % of all samples matched, {:.1f} % not counted: {:.1f} % at rest, {:.1f} % rapids away from the cutting moves, "
            "{:.1f} % tool changes; {:.1f} % of the path reached): not this log's program, or the wrong work offset",
            run.program.file, 100 * q.counted_matched_fraction, mo.max_distance_mm, 100 * settings.min_match, 100 * q.matched_fraction,
            100 * q.excluded_fraction, 100 * double(q.excluded_at_rest) / n, 100 * double(q.excluded_away) / n,
            100 * double(q.excluded_tool_change) / n, 100 * q.coverage));
    }
    if (run.mapped) motion = motion_io::with_mapped_blocks(std::move(motion), run.mapping);
    // The log's own tool channel first; else the program says which tool each block runs.
    if (!names_tools(motion)) {
        std::vector<std::int32_t> tools = program_tools_per_sample(run.program, run.mapping, motion);
        if (std::any_of(tools.begin(), tools.end(), [](std::int32_t t) { return t >= 0; })) {
            motion.tool = std::move(tools);
            run.tools_from_program = true;
        }
    }
    return run;
}

double TimeWarp::operator()(double t) const {
    if (commanded_s.empty()) return t;
    if (t <= commanded_s.front()) return t + (actual_s.front() - commanded_s.front());
    if (t >= commanded_s.back()) return t + (actual_s.back() - commanded_s.back());
    const auto k = static_cast<std::size_t>(std::upper_bound(commanded_s.begin(), commanded_s.end(), t) - commanded_s.begin());
    const double u = (t - commanded_s[k - 1]) / (commanded_s[k] - commanded_s[k - 1]);
    return actual_s[k - 1] + u * (actual_s[k] - actual_s[k - 1]);
}

TimeWarp commanded_to_actual_time(const ProgramRun& run, const motion_io::MotionModel& actual) {
    const std::vector<double> dur = motion_io::commanded_durations_s(run.program, run.commanded);
    // First actual sample the monotone mapping puts on each program block.
    std::vector<double> first_s(run.program.blocks.size(), -1);
    double last_matched_s = -1;
    for (std::size_t i = 0; i < run.mapping.program_block.size() && i < actual.size(); ++i) {
        const std::int32_t b = run.mapping.program_block[i];
        if (b < 0) continue;
        if (first_s[static_cast<std::size_t>(b)] < 0) first_s[static_cast<std::size_t>(b)] = actual.t_s[i];
        last_matched_s = actual.t_s[i];
    }
    TimeWarp w;
    auto knot = [&](double c, double a) {
        // Blocks the machine passed in no time (or matched out of order) are spread over their neighbours.
        if (!w.commanded_s.empty() && (c <= w.commanded_s.back() || a <= w.actual_s.back())) return;
        w.commanded_s.push_back(c);
        w.actual_s.push_back(a);
    };
    double t_begin = 0;
    for (std::size_t i = 0; i < dur.size(); ++i) {
        if (!(dur[i] > 0)) continue;
        if (first_s[i] >= 0) knot(t_begin, first_s[i]);
        t_begin += dur[i];
    }
    if (last_matched_s >= 0) knot(t_begin, last_matched_s);
    return w;
}

ProgramPrediction predict_program(const ProgramRun& run, const motion_io::MotionModel& motion, const Prediction& actual,
                                  const RunSpec& spec, const PredictOptions& options,
                                  const force_model::Rotation3* grid_from_stock, const TurningCommand* turning) {
    ProgramPrediction out;
    if (turning) {
        if (grid_from_stock) throw std::logic_error("predict_program: a turning tool has no fixed frame");
        // Feed overrides index the tip path's pieces, not the machine-axis blocks.
        if (!run.commanded.feed_mm_min.empty()) throw std::logic_error("predict_program: feed overrides of a turning tool's program");
        motion_io::MotionModel axes = motion_io::commanded_motion(*turning->machine_axes, run.commanded);
        program_axes_as_log(axes, *turning->machine_axes, *turning->machine);
        const TurningMotion t = turning_motion(axes, *turning->machine, turning->tool_length_mm);
        out.commanded = force_model::predict_turning(t.motion, t.poses, spec, options);
    } else {
        motion_io::MotionModel commanded = motion_io::commanded_motion(run.program, run.commanded);
        const Eigen::Matrix3d tool_to_stock = grid_from_stock ? tool_to_workpiece(*grid_from_stock) : Eigen::Matrix3d::Identity();
        if (grid_from_stock) turn_motion(commanded, tool_to_stock.transpose());
        out.commanded = force_model::predict(commanded, spec, options);
        if (grid_from_stock) turn_forces(out.commanded.samples, tool_to_stock);
    }
    out.blocks = force_model::compare_program(run.program, motion, run.mapping, out.commanded, actual, run.commanded);
    out.to_actual_time = commanded_to_actual_time(run, motion);
    return out;
}

}  // namespace cutload::app
