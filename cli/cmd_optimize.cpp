// cutload optimize LOG --spec RUN.json --program PROG.nc --target 0.8 --out PROG_OPT.nc
// Per block, the feed that brings the binding load (peak force, torque, power, chip thickness or
// bending stress) to the target fraction of its limit; writes the program back with only the F
// words changed and shows the prediction at the new feeds.
#include "commands.hpp"
#include "predict_program.hpp"
#include "app/optimize.hpp"
#include "textio/csv.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <memory>

namespace cutload::cli {
namespace {

struct OptimizeArgs {
    std::string log, spec, out, report, device = "auto", basis = "actual";
    double target = 0.8, min_feed = 10, max_feed = 0;
    int max_predictions = 8;
    bool quiet = false;
    double step_ms = motion_io::ReadOptions{}.step_ms;
    app::LogFormat format;
    ProgramOptions program;
};

void write_report(const force_model::FeedOptimization& r, const std::string& path) {
    std::ofstream out(path, std::ios::trunc);
    if (!out) throw UsageError("cannot write " + path, 1);
    out << "block,programmed_feed_mm_min,recommended_feed_mm_min,binding,ratio_before,ratio_after,at_feed_limit\n";
    for (const auto& b : r.blocks)
        out << fmt::format("{},{:.1f},{:.1f},{},{:.4f},{:.4f},{}\n", textio::csv_field(b.block), b.programmed_feed_mm_min,
                           b.recommended_feed_mm_min, b.binding, b.ratio_before, b.ratio_after, b.at_feed_limit ? 1 : 0);
    if (!out) throw UsageError("writing " + path + " failed", 1);
}

void run_optimize(const OptimizeArgs& a) {
    app::OptimizeInput in;
    in.spec = force_model::load_run_spec(a.spec);
    in.log_path = a.log;
    in.read = reader_options(a.format, a.step_ms);
    in.program = program_source(a.program).value();   // --program is required
    in.device = choose_device(a.device);
    force_model::FeedOptimizerOptions& o = in.search;
    o.target = a.target;
    o.min_feed_mm_min = a.min_feed;
    o.max_feed_mm_min = a.max_feed;
    o.max_predictions = a.max_predictions;
    o.basis = a.basis == "commanded" ? force_model::FeedBasis::Commanded : force_model::FeedBasis::Actual;
    app::Control control;
    if (!a.quiet)
        control.progress = [noted = false](app::Phase phase, double) mutable {
            if (phase != app::Phase::Optimize || noted) return;
            std::fprintf(stderr, "optimizing feeds (a few predictions)...\n");
            noted = true;
        };
    const app::OptimizeResult result = app::optimize_feeds(in, control);
    print_mapping(result.program);
    const force_model::FeedOptimization& r = result.feeds;

    {
        std::ofstream out(a.out, std::ios::binary | std::ios::trunc);
        if (!out) throw UsageError("cannot write " + a.out, 1);
        out << result.program_text;
        if (!out) throw UsageError("writing " + a.out + " failed", 1);
    }
    if (!a.report.empty()) write_report(r, a.report);

    std::printf("%-8s %9s %9s %-8s %8s %8s\n", "block", "F_prog", "F_new", "binding", "before", "after");
    for (const auto& b : r.blocks)
        std::printf("%-8s %9.0f %9.0f %-8s %7.1f%% %7.1f%%%s\n", b.block.c_str(), b.programmed_feed_mm_min,
                    b.recommended_feed_mm_min, b.binding.c_str(), 100 * b.ratio_before, 100 * b.ratio_after,
                    b.at_feed_limit ? "  (feed range)" : "");
    std::size_t in_band = 0, below = 0, over = 0;
    for (const auto& b : r.blocks) {
        if (b.ratio_after > a.target + 1e-9) ++over;
        else if (b.ratio_after >= a.target * (1 - o.tolerance) || b.at_feed_limit) ++in_band;
        else ++below;
    }
    std::printf("%zu of %zu cutting blocks changed; %d predictions (basis: %s)\n", result.changed_blocks, r.blocks.size(),
                r.predictions, a.basis.c_str());
    std::printf("target %.0f%%: %zu blocks at it (or at the feed range), %zu below, %zu over; highest load after: %.1f%% of "
                "its limit; cycle %.3f s -> %.3f s; program -> %s\n",
                100 * a.target, in_band, below, over, 100 * r.max_ratio_after, r.before.stats.simulated_s,
                r.after.stats.simulated_s, a.out.c_str());
    if (r.max_ratio_after > 1)
        std::fprintf(stderr, "cutload: warning: with the new feeds %s still exceeds a limit (%.1f %% of it)%s\n",
                     r.max_ratio_block.c_str(), 100 * r.max_ratio_after,
                     std::any_of(r.blocks.begin(), r.blocks.end(), [&](const auto& b) { return b.block == r.max_ratio_block; })
                         ? ""
                         : ": its feed is not an F word the optimizer sets (a rapid, or a block that does not cut)");
}

void add_optimize(CLI::App& app) {
    auto a = std::make_shared<OptimizeArgs>();
    auto* cmd = app.add_subcommand("optimize", "Recommend per-block feeds that load the tool to a target fraction of its limits");
    cmd->add_option("LOG", a->log, "Dry-run motion log (CSV or SHDR) of the program")->required()->check(CLI::ExistingFile);
    cmd->add_option("--spec", a->spec, "Run spec (RUN.json) with the limits to aim at")->required()->check(CLI::ExistingFile);
    cmd->add_option("--out", a->out, "The program with the recommended F words")->required();
    cmd->add_option("--target", a->target, "Fraction of each limit the binding load is brought to")
        ->check(CLI::Range(0.05, 1.0))
        ->capture_default_str();
    cmd->add_option("--min-feed", a->min_feed, "Lowest feed the machine takes, mm/min")->check(CLI::PositiveNumber)->capture_default_str();
    cmd->add_option("--max-feed", a->max_feed, "Highest cutting feed, mm/min (default: 90% of limits.rapid_feed_mm_min)")
        ->check(CLI::PositiveNumber);
    cmd->add_option("--basis", a->basis, "Predict from the log's actual motion retimed to the new feeds, or from the program")
        ->check(CLI::IsMember({"actual", "commanded"}))
        ->capture_default_str();
    cmd->add_option("--max-predictions", a->max_predictions, "Force predictions the search may run")
        ->check(CLI::Range(2, 20))
        ->capture_default_str();
    cmd->add_option("--report", a->report, "FEEDS.csv: per block programmed and recommended feed, binding load, before/after");
    cmd->add_option("--device", a->device, "opencl, cpu, or auto (OpenCL when a device exists)")
        ->check(CLI::IsMember({"opencl", "cpu", "auto"}))
        ->capture_default_str();
    cmd->add_option("--step-ms", a->step_ms, "Resampling step of the motion model in ms")
        ->check(CLI::PositiveNumber)
        ->capture_default_str();
    cmd->add_flag("-q,--quiet", a->quiet, "No progress note");
    add_program_options(*cmd, a->program, false);
    add_log_options(*cmd, a->format);
    cmd->callback([a] {
        check_output_path(a->out, "--out");
        if (!a->report.empty()) check_output_path(a->report, "--report");
        run_optimize(*a);
    });
}

const bool registered = register_command("optimize", &add_optimize);

}  // namespace
}  // namespace cutload::cli
