// cutload resample LOG --step-ms S --out FILE.csv [--format csv|shdr] [--map FILE] [--units mm|in] [--feed-units U]
#include "commands.hpp"
#include "app/ingest.hpp"

#include <fmt/format.h>

#include <memory>

namespace cutload::cli {
namespace {

struct ResampleArgs {
    std::string log, out;
    app::LogFormat format;
    double step_ms = 0;
};

void add_resample(CLI::App& app) {
    auto args = std::make_shared<ResampleArgs>();
    auto* sub = app.add_subcommand(
        "resample", "Repair a log's sampling and write it on a uniform time step as CSV "
                    "(t_s,x_mm,y_mm,z_mm,feed_mm_min,spindle_rpm,spindle_angle_deg,block)");
    sub->add_option("LOG", args->log, "Motion log (CSV or MTConnect SHDR)")->required();
    sub->add_option("--step-ms", args->step_ms, "Uniform time step in milliseconds")->required();
    sub->add_option("--out", args->out, "Output CSV (written only when the whole log was read)")->required();
    add_log_options(*sub, args->format);
    sub->callback([args] {
        check_output_path(args->out, "--out");
        if (!(args->step_ms >= 0.01 && args->step_ms <= 1000))
            throw UsageError(fmt::format("--step-ms: must be from 0.01 to 1000 ms, got {}", args->step_ms));
        const app::Resampled r = app::resample_log(args->log, reader_options(args->format, args->step_ms), args->out);
        const motion_io::IngestReport& report = r.report;
        const std::size_t rows = r.rows;
        fmt::print("wrote {} rows ({:.3f} s in {} session{}, {} warning code{}) to {}\n", rows, report.duration_s,
                   report.sessions, report.sessions == 1 ? "" : "s", report.warnings.size(),
                   report.warnings.size() == 1 ? "" : "s", args->out);
    });
}

const bool registered = register_command("resample", &add_resample);

}  // namespace
}  // namespace cutload::cli
