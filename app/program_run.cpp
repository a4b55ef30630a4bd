#include "app/program_run.hpp"

#include <fmt/format.h>

#include <algorithm>
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

}  // namespace

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
    ro.arc_tolerance_mm = settings.arc_tolerance_mm;
    ro.tool_change_on_t = settings.tool_change_on_t;
    ro.block_skip = settings.block_skip;
    ro.rapid_mm_min = settings.rapid_mm_min;
    ro.limits = settings.limits;
    ro.start_mm = start_mm;
    return ro;
}

ProgramRun prepare_program_run(motion_io::NcProgram program, const ProgramSettings& settings,
                               motion_io::MotionModel& motion) {
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
    run.mapped = settings.map_blocks || !log_blocks_match(motion, run.program);
    if (!run.mapped) {
        // Deviations do not depend on the lead; the agreement is reported at the calibrated one.
        run.estimated_lead_s = motion_io::estimate_block_lead_s(motion, run.program, mo);
        mo.lead_s = *run.estimated_lead_s;
    }
    run.mapping = motion_io::map_blocks(motion, run.program, mo);
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
                                  const RunSpec& spec, const PredictOptions& options) {
    ProgramPrediction out;
    out.commanded = force_model::predict(motion_io::commanded_motion(run.program, run.commanded), spec, options);
    out.blocks = force_model::compare_program(run.program, motion, run.mapping, out.commanded, actual, run.commanded);
    out.to_actual_time = commanded_to_actual_time(run, motion);
    return out;
}

}  // namespace cutload::app
