#include "app/work_bounds.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace cutload::app {
namespace {

// The commanded motion's extent from the program alone: commanded_motion() samples each block's
// time at the log's step and turns the spindle at the block's programmed speed throughout it.
motion_io::MotionExtent program_extent(const motion_io::NcProgram& program, const motion_io::CommandedOptions& options,
                                       double& duration_s) {
    const std::vector<double> durations_s = motion_io::commanded_durations_s(program, options);
    motion_io::MotionExtent e;
    duration_s = 0;
    for (std::size_t i = 0; i < durations_s.size() && i < program.blocks.size(); ++i) {
        duration_s += durations_s[i];
        e.spindle_turned_deg += durations_s[i] * std::abs(program.blocks[i].spindle_rpm) * 6.0;   // rpm -> deg/s
    }
    e.samples = std::size_t(motion_io::commanded_sample_count(program, options));
    return e;
}

}  // namespace

WorkEstimate estimate_work(const motion_io::IngestReport& log, const force_model::RunSpec& spec,
                           const CommandedWork& commanded, bool actual_rows_streamed) {
    WorkEstimate w;
    w.log_duration_s = log.duration_s;
    w.spindle_max_rpm = log.spindle_max_rpm;
    w.spindle_revolutions = log.extent.spindle_turned_deg / 360;
    w.angle_step_deg = spec.resolution.angle_step_deg;
    w.force_rows = double(force_model::expected_rows(log.extent, w.angle_step_deg));
    w.motion_samples = double(log.extent.samples);
    if (commanded.program) {
        const motion_io::MotionExtent e = program_extent(*commanded.program, commanded.options, w.commanded_duration_s);
        w.commanded_revolutions = e.spindle_turned_deg / 360;
        w.commanded_rows = double(force_model::expected_rows(e, w.angle_step_deg));
        w.motion_samples += double(e.samples);
        w.stocks = 2;
    } else if (commanded.from_log) {
        w.commanded_duration_s = w.log_duration_s;
        w.commanded_revolutions = w.spindle_revolutions;
        w.commanded_rows = w.force_rows;
        w.motion_samples *= 2;
        w.stocks = 2;
    }
    w.stock_cells = force_model::stock_cells(spec.stock, spec.resolution.grid_mm);
    const double rows_held = actual_rows_streamed ? w.commanded_rows : w.total_rows();
    const double bytes = rows_held * kJobBytesPerForceRow + w.motion_samples * kJobBytesPerMotionSample +
                         w.stock_cells * (double(w.stocks) * double(force_model::stock_bytes_per_cell()) +
                                          kJobBytesPerStoredCell);
    w.memory_mb = bytes / (1024.0 * 1024.0);
    return w;
}

void check_work(const WorkEstimate& w, const WorkLimits& limits) {
    if (w.stock_cells > limits.max_stock_cells)
        throw TooMuchWork("stock_cells",
                          fmt::format("resolution.grid_mm gives the stock box {:.4g} dexel cells, above the limit of {:.4g} "
                                      "(--max-stock-cells): use a coarser grid or a smaller stock",
                                      w.stock_cells, limits.max_stock_cells));
    if (w.total_rows() > limits.max_force_rows) {
        std::string what = fmt::format("the log's {:.4g} s turn the spindle {:.4g} revolutions (up to {:.0f} rpm)",
                                       w.log_duration_s, w.spindle_revolutions, w.spindle_max_rpm);
        if (w.commanded_rows > 0)
            what += fmt::format(" and the commanded motion's {:.4g} s {:.4g} revolutions", w.commanded_duration_s,
                                w.commanded_revolutions);
        throw TooMuchWork("force_rows",
                          fmt::format("{}; at resolution.angle_step_deg {:g} that is {:.3g} force rows, above the limit of "
                                      "{:.3g} (--max-force-rows): use a larger angle step or a shorter log",
                                      what, w.angle_step_deg, w.total_rows(), limits.max_force_rows));
    }
    if (w.memory_mb > limits.max_job_memory_mb)
        throw TooMuchWork("job_memory",
                          fmt::format("the run would need about {:.0f} MB ({:.3g} force rows, {:.3g} stock cells x {}, "
                                      "{:.3g} motion samples), above the limit of {:.0f} MB (--max-job-memory-mb): use "
                                      "a larger angle step, a coarser grid or a shorter log",
                                      w.memory_mb, w.total_rows(), w.stock_cells, w.stocks, w.motion_samples,
                                      limits.max_job_memory_mb));
}

std::size_t max_rows(const WorkLimits& limits) {
    return limits.max_force_rows > 0 ? std::size_t(std::min(limits.max_force_rows, 1e18)) : 0;
}

}  // namespace cutload::app
