#include "predict_program.hpp"

#include "commands.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cstdio>
#include <sstream>

namespace cutload::cli {
namespace {

std::pair<std::string, std::array<double, 3>> parse_work_offset(const std::string& s) {
    const auto eq = s.find('=');
    const std::string name = eq == std::string::npos ? "" : s.substr(0, eq);
    std::array<double, 3> v{};
    bool ok = name.size() == 3 && (name[0] == 'G' || name[0] == 'g') && name[1] == '5' && name[2] >= '4' && name[2] <= '9';
    if (ok) {
        std::istringstream in(s.substr(eq + 1));
        char c1 = 0, c2 = 0;
        in >> v[0] >> c1 >> v[1] >> c2 >> v[2];
        ok = in && c1 == ',' && c2 == ',' && (in >> std::ws).eof();
    }
    if (!ok) throw UsageError(fmt::format("--work-offset '{}': expected G54..G59=X,Y,Z (mm), e.g. G55=200,-300,-350", s));
    return {"G" + name.substr(1), v};
}

// The cutting blocks' commanded-vs-actual rows, then where the outputs went.
void print_comparison(const std::vector<force_model::BlockComparison>& rows, const force_model::Prediction& commanded,
                      const ProgramOptions& o) {
    std::printf("%-8s %8s %9s %9s %8s %8s %10s %10s %9s\n", "block", "F", "dev_max", "dev_mean", "deficit", "surge",
                "F_cmd_N", "F_act_N", "diff");
    for (const auto& r : rows) {
        if (r.commanded_peak_force_N <= 0 && r.actual_peak_force_N <= 0) continue;
        std::printf("%-8s %8.0f %8.3fmm %8.3fmm %7.1f%% %7.1f%% %10.1f %10.1f %+8.1f%%\n", r.block.c_str(),
                    r.programmed_feed_mm_min, r.max_deviation_mm, r.mean_deviation_mm, r.feed_deficit_pct, r.feed_surge_pct,
                    r.commanded_peak_force_N, r.actual_peak_force_N, r.force_difference_pct);
    }
    std::printf("commanded prediction: %.3f s simulated%s%s%s%s\n", commanded.stats.simulated_s,
                o.commanded_out.empty() ? "" : "; forces -> ", o.commanded_out.c_str(),
                o.compare_csv.empty() ? "" : "; comparison -> ", o.compare_csv.c_str());
}

}  // namespace

void add_program_options(CLI::App& cmd, ProgramOptions& o, bool for_predict) {
    auto* program = cmd.add_option("--program", o.program, "NC program (ISO 6983, FANUC dialect) the log is a dry run of")
                        ->check(CLI::ExistingFile);
    if (!for_predict) program->required();
    cmd.add_option("--work-offset", o.work_offsets,
                   "Work offset as G54..G59=X,Y,Z: machine position of the program's tool-tip zero, mm "
                   "(default G54 = -setup.offset_mm of the run spec); repeatable");
    cmd.add_option("--ignore", o.ignore, "NC words to drop before interpretation, e.g. G28 or H (comma-separated)")
        ->delimiter(',');
    cmd.add_option("--rapid-feed", o.rapid_mm_min, "G00 rate of the machine, mm/min (commanded motion)")
        ->check(CLI::Range(o.limits.min_rapid_mm_min, o.limits.max_rapid_mm_min))
        ->capture_default_str();
    cmd.add_option("--arc-centers", o.arc_centers, "Arc centres I/J/K until the program says G90.1/G91.1: incremental (from the arc's start) or absolute")
        ->check(CLI::IsMember({"incremental", "absolute"}))
        ->capture_default_str();
    cmd.add_option("--program-units", o.program_units, "Length unit of a program until it says G20/G21: mm or in")
        ->check(CLI::IsMember({"mm", "in"}))
        ->capture_default_str();
    cmd.add_option("--rotary-feed", o.rotary_feed,
                   "With --machine: how a G94 feed applies to a G01 that turns a rotary axis: combined (F over "
                   "sqrt(dX^2+dY^2+dZ^2+dA^2+dB^2+dC^2), degrees as mm, FANUC) or linear_only (F over the X/Y/Z travel; "
                   "deg/min for a pure turn)")
        ->check(CLI::IsMember({"combined", "linear_only"}))
        ->capture_default_str();
    cmd.add_option("--arc-tolerance-mm", o.arc_tolerance_mm,
                   "How far an arc's end may lie off the circle through its start, mm (plus 0.01 % of the radius)")
        ->check(CLI::Range(0.0, 10.0))
        ->capture_default_str();
    cmd.add_flag("--tool-change-on-t", o.tool_change_on_t, "The control changes tools on T alone (no M06)");
    cmd.add_flag("--block-skip", o.block_skip, "The block skip switch is on: blocks starting with '/' are skipped");
    cmd.add_option("--min-match", o.min_match,
                   "Refuse the program when fewer of the log's counted samples lie near its path (samples at rest, rapids away "
                   "from the cutting moves and tool changes are not counted)")
        ->check(CLI::Range(0.0, 1.0))
        ->capture_default_str();
    cmd.add_option("--max-program-path-mm", o.limits.max_path_mm, "Refuse a program whose programmed path is longer, mm")
        ->check(CLI::PositiveNumber)
        ->capture_default_str();
    cmd.add_option("--max-program-duration-s", o.limits.max_duration_s, "Refuse a program that runs longer at its feeds, s")
        ->check(CLI::PositiveNumber)
        ->capture_default_str();
    cmd.add_option("--max-commanded-samples", o.limits.max_samples, "Refuse a program whose commanded motion takes more samples")
        ->check(CLI::PositiveNumber)
        ->capture_default_str();
    cmd.add_option("--block-lead-ms", o.block_lead_ms,
                   "Block mapping: how far the CNC's block counter runs ahead of the actual position, ms "
                   "(printed as 'calibrated lead' when a log with blocks is mapped)")
        ->check(CLI::Range(0.0, 10000.0))
        ->capture_default_str();
    cmd.add_flag("--map-blocks", o.map_blocks, "Attribute samples to blocks by mapping, even if the log names blocks");
    cmd.add_flag("--no-decimal-is-increment", o.decimal_less_increment,
                 "X10 without a decimal point means 10 least increments (FANUC parameter 3401#0 = 0)");
    if (for_predict) {
        cmd.add_option("--compare", o.compare_csv,
                       "Per-block commanded-vs-actual comparison CSV (with --program or --commanded-from-log)");
        cmd.add_option("--commanded-out", o.commanded_out,
                       "FORCES.csv of the commanded motion (with --program or --commanded-from-log)");
        cmd.add_flag("--commanded-from-log", o.commanded_from_log,
                     "Take the commanded path from the log's own commanded positions (x_cmd, y_cmd, z_cmd or the map's) "
                     "instead of an NC program: predict it and compare it with the actual motion block by block");
    }
}

std::optional<app::ProgramSource> program_source(const ProgramOptions& o) {
    if (o.commanded_from_log && !o.program.empty())
        throw UsageError("--commanded-from-log and --program both give the commanded path: choose one");
    if (o.program.empty()) {
        if ((!o.compare_csv.empty() || !o.commanded_out.empty()) && !o.commanded_from_log)
            throw UsageError("--compare and --commanded-out need --program or --commanded-from-log");
        return std::nullopt;
    }
    app::ProgramSource source;
    source.path = o.program;
    app::ProgramSettings& settings = source.settings;
    for (const std::string& w : o.work_offsets) {
        const auto [name, v] = parse_work_offset(w);
        settings.work_offsets_mm[name] = v;
    }
    settings.ignore_words = o.ignore;
    settings.decimal_less_is_increment = o.decimal_less_increment;
    settings.rapid_mm_min = o.rapid_mm_min;
    settings.block_lead_ms = o.block_lead_ms;
    settings.map_blocks = o.map_blocks;
    settings.arc_centers = o.arc_centers == "absolute" ? motion_io::ArcCenters::Absolute : motion_io::ArcCenters::Incremental;
    settings.program_units = o.program_units == "in" ? motion_io::ProgramUnits::Inch : motion_io::ProgramUnits::Mm;
    settings.rotary_feed = *motion_io::parse_rotary_feed(o.rotary_feed);   // CLI::IsMember checked the spelling
    settings.arc_tolerance_mm = o.arc_tolerance_mm;
    settings.tool_change_on_t = o.tool_change_on_t;
    settings.block_skip = o.block_skip;
    settings.min_match = o.min_match;
    settings.limits = o.limits;   // the app sets the sample step from the log
    return source;
}

void print_mapping(const app::ProgramRun& run) {
    const auto& q = run.mapping.quality;
    std::printf("program: %zu blocks; log blocks %s; matched %.1f%% of samples, deviation mean %.3f / p95 %.3f / max %.3f mm, "
                "path covered %.1f%%\n",
                run.program.blocks.size(), run.mapped ? "by mapping" : "from the log", 100 * q.matched_fraction,
                q.mean_distance_mm, q.p95_distance_mm, q.max_distance_mm, 100 * q.coverage);
    if (q.excluded_fraction > 0) {
        const double n = double(q.samples);
        std::printf("  not counted: %.1f%% of samples (%.1f%% at rest, %.1f%% rapids away from the cutting moves, %.1f%% tool "
                    "changes); matched %.1f%% of the counted\n",
                    100 * q.excluded_fraction, 100 * double(q.excluded_at_rest) / n, 100 * double(q.excluded_away) / n,
                    100 * double(q.excluded_tool_change) / n, 100 * q.counted_matched_fraction);
    }
    if (q.agreement) std::printf("  mapping agrees with the log's blocks on %.2f%% of samples\n", 100 * *q.agreement);
    if (run.estimated_lead_s) std::printf("  calibrated lead of the log's block channel: %.0f ms (--block-lead-ms for logs without blocks)\n", *run.estimated_lead_s * 1e3);
    if (!q.blocks_without_samples.empty()) {
        std::string names;
        for (std::size_t i = 0; i < q.blocks_without_samples.size() && i < 8; ++i) names += " " + q.blocks_without_samples[i];
        std::printf("  %zu moving blocks got no samples:%s%s\n", q.blocks_without_samples.size(), names.c_str(),
                    q.blocks_without_samples.size() > 8 ? " ..." : "");
    }
}

void finish_program_run(const ProgramOptions& o, const app::RunResult& r, const std::string& blocks_csv) {
    if (!r.commanded) return;
    const force_model::Prediction& commanded = r.commanded->commanded;
    const std::vector<force_model::BlockComparison>& rows = r.commanded->blocks;
    if (!o.commanded_out.empty()) force_model::write_forces_file(commanded, o.commanded_out);
    if (!o.compare_csv.empty()) force_model::write_comparison_csv(rows, o.compare_csv);
    if (!blocks_csv.empty())
        force_model::write_blocks_csv(r.prediction, blocks_csv, force_model::comparison_block_columns(rows));
    if (r.program)
        print_mapping(*r.program);
    else
        std::printf("commanded path: the log's commanded positions (%zu samples)\n", r.commanded_samples);
    print_comparison(rows, commanded, o);
}

}  // namespace cutload::cli
