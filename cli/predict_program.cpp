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
        ->check(CLI::PositiveNumber)
        ->capture_default_str();
    cmd.add_option("--block-lead-ms", o.block_lead_ms,
                   "Block mapping: how far the CNC's block counter runs ahead of the actual position, ms "
                   "(printed as 'calibrated lead' when a log with blocks is mapped)")
        ->check(CLI::NonNegativeNumber)
        ->capture_default_str();
    cmd.add_flag("--map-blocks", o.map_blocks, "Attribute samples to blocks by mapping, even if the log names blocks");
    cmd.add_flag("--no-decimal-is-increment", o.decimal_less_increment,
                 "X10 without a decimal point means 10 least increments (FANUC parameter 3401#0 = 0)");
    if (for_predict) {
        cmd.add_option("--compare", o.compare_csv, "Per-block commanded-vs-actual comparison CSV (with --program)");
        cmd.add_option("--commanded-out", o.commanded_out, "FORCES.csv of the commanded motion (with --program)");
    }
}

std::optional<app::ProgramSource> program_source(const ProgramOptions& o) {
    if (o.program.empty()) {
        if (!o.compare_csv.empty() || !o.commanded_out.empty()) throw UsageError("--compare and --commanded-out need --program");
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
    return source;
}

void print_mapping(const app::ProgramRun& run) {
    const auto& q = run.mapping.quality;
    std::printf("program: %zu blocks; log blocks %s; matched %.1f%% of samples, deviation mean %.3f / p95 %.3f / max %.3f mm, "
                "path covered %.1f%%\n",
                run.program.blocks.size(), run.mapped ? "by mapping" : "from the log", 100 * q.matched_fraction,
                q.mean_distance_mm, q.p95_distance_mm, q.max_distance_mm, 100 * q.coverage);
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
    if (!r.program || !r.commanded) return;
    const force_model::Prediction& commanded = r.commanded->commanded;
    const std::vector<force_model::BlockComparison>& rows = r.commanded->blocks;
    if (!o.commanded_out.empty()) force_model::write_forces_csv(commanded, o.commanded_out);
    if (!o.compare_csv.empty()) force_model::write_comparison_csv(rows, o.compare_csv);
    if (!blocks_csv.empty())
        force_model::write_blocks_csv(r.prediction, blocks_csv, force_model::comparison_block_columns(rows));
    print_mapping(*r.program);
    std::printf("%-8s %8s %9s %9s %8s %8s %10s %10s %9s\n", "block", "F", "dev_max", "dev_mean", "deficit", "surge",
                "F_cmd_N", "F_act_N", "diff");
    for (const auto& b : rows) {
        if (b.commanded_peak_force_N <= 0 && b.actual_peak_force_N <= 0) continue;
        std::printf("%-8s %8.0f %8.3fmm %8.3fmm %7.1f%% %7.1f%% %10.1f %10.1f %+8.1f%%\n", b.block.c_str(),
                    b.programmed_feed_mm_min, b.max_deviation_mm, b.mean_deviation_mm, b.feed_deficit_pct, b.feed_surge_pct,
                    b.commanded_peak_force_N, b.actual_peak_force_N, b.force_difference_pct);
    }
    std::printf("commanded prediction: %.3f s simulated%s%s%s%s\n", commanded.stats.simulated_s,
                o.commanded_out.empty() ? "" : "; forces -> ", o.commanded_out.c_str(),
                o.compare_csv.empty() ? "" : "; comparison -> ", o.compare_csv.c_str());
}

}  // namespace cutload::cli
