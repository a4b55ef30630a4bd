// Ingest + repair of a 1,000,000-row CSV log in the seed's sampling pattern.
// Targets (issue 2): under 2 s and under 300 MB peak on the 2-core CI machine.
// Prints rows/s, the median of several runs, and the peak resident memory.
#include "bench_util.hpp"
#include "motion_io/motion_io.hpp"
#include "motion_io/synth.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <sys/resource.h>

using namespace cutload::motion_io;
using namespace cutload::bench;

int main() {
    constexpr std::size_t kRows = 1'000'000;
    const std::string path = (std::filesystem::temp_directory_path() / "cutload_bench_ingest_1M.csv").string();
    {
        // The demo program over and over: rapids, ramps, slots, corners; about 6000 s of log.
        DryRunSpec spec = demo_dry_run_spec();
        const auto one = spec.program;
        for (int k = 0; k < 450; ++k) spec.program.insert(spec.program.end(), one.begin(), one.end());
        spec.max_rows = kRows;
        std::ofstream out(path, std::ios::binary);
        const auto t0 = std::chrono::steady_clock::now();
        const std::size_t rows = synthesize_dry_run(spec, out);
        out.close();
        std::printf("generated %zu rows (%.1f MB) in %.2f s: %s\n", rows, std::filesystem::file_size(path) / 1e6,
                    std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), path.c_str());
    }
    const double mem_before = peak_rss_mb();

    // Streaming: parse, validate, align, drop stale repeats, recover the CNC clock, velocity,
    // Hermite resample at 1 ms, spindle angle, blocks; the grid is not kept.
    ReadOptions opt;
    opt.step_ms = 1.0;
    IngestReport report;
    const Timing t_stream = median_seconds(5, [&] { report = inspect(path, opt); });
    const double mem_stream = peak_rss_mb();
    std::printf("inspect  (full pipeline, 1 ms grid, streamed): median %.3f s wall (%.3f s CPU) = %.0f rows/s, "
                "peak %.0f MB (%.0f MB before); CNC update %.3f ms, %zu stale dropped\n",
                t_stream.wall_s, t_stream.cpu_s, kRows / t_stream.wall_s, mem_stream, mem_before,
                report.channels["pos"].update_period_s * 1e3, report.channels["pos"].stale_dropped);

    // In memory: the MotionModel at the log's own 6 ms cadence (at 1 ms the model alone would
    // hold 6 million samples, about 550 MB).
    opt.step_ms = 6.0;
    std::size_t samples = 0;
    const Timing t_model = median_seconds(5, [&] { samples = ingest(path, opt).size(); });
    std::printf("ingest   (MotionModel, 6 ms grid, %zu samples): median %.3f s wall (%.3f s CPU) = %.0f rows/s, "
                "peak %.0f MB\n", samples, t_model.wall_s, t_model.cpu_s, kRows / t_model.wall_s, peak_rss_mb());
    std::printf("targets: < 2 s, < 300 MB peak\n");
    std::filesystem::remove(path);
    return 0;
}
