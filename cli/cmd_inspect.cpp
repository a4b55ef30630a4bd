// cutload inspect LOG [--format csv|shdr] [--map FILE] [--units mm|in] [--feed-units U] [--json]
#include "commands.hpp"
#include "app/ingest.hpp"

#include <nlohmann/json.hpp>

#include <fmt/format.h>

#include <iostream>
#include <memory>

namespace cutload::cli {
namespace {

struct InspectArgs {
    std::string log;
    app::LogFormat format;
    bool json = false;
};

void print_text(const motion_io::IngestReport& r) {
    fmt::print("{} ({})\n", r.file, r.format);
    fmt::print("  duration      {:.3f} s in {} session{}\n", r.duration_s, r.sessions, r.sessions == 1 ? "" : "s");
    fmt::print("  blocks        {}\n", r.blocks);
    fmt::print("  channel       samples   interval min / median / max [ms]   CNC update [ms]   stale dropped\n");
    for (const auto& [name, c] : r.channels) {
        fmt::print("  {:<12}{:>9}   {:>9.3f} / {:>8.3f} / {:>10.3f}   {:>15}   {:>13}\n", name, c.samples,
                   c.interval.min_s * 1e3, c.interval.median_s * 1e3, c.interval.max_s * 1e3,
                   c.update_period_s > 0 ? fmt::format("{:.3f}", c.update_period_s * 1e3) : std::string("-"),
                   c.stale_dropped);
    }
    fmt::print("  feed raw      {:.0f} .. {:.0f} mm/min (plain differencing)\n", r.feed_raw_min_mm_min, r.feed_raw_max_mm_min);
    fmt::print("  feed repaired {:.0f} .. {:.0f} mm/min\n", r.feed_repaired_min_mm_min, r.feed_repaired_max_mm_min);
    fmt::print("  position step {}\n", r.position_step_mm ? fmt::format("{:g} mm (as written)", *r.position_step_mm) : "unknown (too few moves)");
    fmt::print("  spindle max   {:.0f} rpm\n", r.spindle_max_rpm);
    if (!r.rotary_axes.empty())
        fmt::print("  rotary        {} (deg, unwrapped; predict --machine turns them into the tool's motion)\n",
                   r.rotary_axes);
    if (r.commanded_positions) fmt::print("  commanded     the log also holds commanded positions (predict --commanded-from-log)\n");
    fmt::print("  warnings      {}\n", r.warnings.empty() ? "none" : "");
    for (const auto& w : r.warnings) fmt::print("    {}: {}\n", w.code, w.message);
}

void add_inspect(CLI::App& app) {
    auto args = std::make_shared<InspectArgs>();
    auto* sub = app.add_subcommand("inspect", "Read a dry-run log and report its sampling, sessions, blocks and warnings");
    sub->add_option("LOG", args->log, "Motion log (CSV or MTConnect SHDR)")->required();
    add_log_options(*sub, args->format);
    sub->add_flag("--json", args->json, "Print one JSON object instead of text");
    sub->callback([args] {
        const motion_io::IngestReport report = app::inspect_log(args->log, reader_options(args->format));
        if (args->json)
            std::cout << motion_io::report_to_json(report).dump(2) << "\n";
        else
            print_text(report);
    });
}

const bool registered = register_command("inspect", &add_inspect);

}  // namespace
}  // namespace cutload::cli
