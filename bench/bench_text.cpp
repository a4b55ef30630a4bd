// The text layer's cost where it matters: a 2,000,000-row DynoWare export (about 65 MB) read by
// read_measurement (docs/compare_calibrate.md quotes the figure), and the raw CSV reader over the
// same bytes, all ASCII and with every tenth line holding a Latin-1 byte (decoded on the way).
// Prints medians of 5 runs (wall and CPU seconds, MB/s) and the load average: wall times on the
// shared machine mean little when it is busy, CPU times still do.
#include "bench_util.hpp"
#include "force_model/measurement.hpp"

#if __has_include("textio/csv.hpp")
#include "textio/csv.hpp"
#define CUTLOAD_BENCH_TEXTIO 1
#endif

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <sys/resource.h>

using namespace cutload::bench;

namespace {

// A DynoWare export at 50 kHz; `latin1` puts a Latin-1 degree sign into every tenth line's Mz unit.
void write_dynoware(const std::string& path, std::size_t rows, bool latin1) {
    std::ofstream out(path, std::ios::binary);
    out << "DynoWare,Version 3.2.2.0\nMeasurement:,bench\nSampling rate [Hz]:,50000\nTime,Fx,Fy,Fz,Mz\ns,N,N,N,N*cm\n";
    std::string buf;
    char line[128];
    for (std::size_t i = 0; i < rows; ++i) {
        const double t = static_cast<double>(i) / 50000.0;
        const int n = std::snprintf(line, sizeof line, "%.5f,%.3f,%.3f,%.3f,%s\n", t, 100 * std::sin(t * 700.0),
                                    -80 * std::cos(t * 700.0), 30.0 + 0.001 * static_cast<double>(i % 997),
                                    latin1 && i % 10 == 0 ? "0.1\xB0" : "0.1");
        buf.append(line, static_cast<std::size_t>(n));
        if (buf.size() > (1 << 20)) {
            out << buf;
            buf.clear();
        }
    }
    out << buf;
}

}  // namespace

int main() {
    constexpr std::size_t kRows = 2'000'000;
    const std::string path = (std::filesystem::temp_directory_path() / "cutload_bench_text_2M.csv").string();
    write_dynoware(path, kRows, false);
    const double mb = static_cast<double>(std::filesystem::file_size(path)) / 1e6;
    std::printf("DynoWare export: %zu rows, %.1f MB; load average %s\n", kRows, mb, load_average().c_str());

    std::size_t samples = 0;
    const Timing t_meas = median_seconds(5, [&] { samples = cutload::force_model::read_measurement(path).size(); });
    std::printf("read_measurement: %zu samples, median %.3f s wall (%.3f s CPU), %.0f MB/s CPU\n", samples, t_meas.wall_s,
                t_meas.cpu_s, mb / t_meas.cpu_s);

#ifdef CUTLOAD_BENCH_TEXTIO
    auto scan = [&](const std::string& file) {
        std::ifstream in(file, std::ios::binary);
        cutload::textio::CsvReader csv(in, file);
        std::size_t fields = 0;
        while (csv.next()) fields += csv.size();
        return fields;
    };
    std::size_t fields = 0;
    const Timing t_ascii = median_seconds(5, [&] { fields = scan(path); });
    std::printf("textio::CsvReader, ASCII: %zu fields, median %.3f s wall (%.3f s CPU), %.0f MB/s CPU\n", fields,
                t_ascii.wall_s, t_ascii.cpu_s, mb / t_ascii.cpu_s);
    write_dynoware(path, kRows, true);
    const Timing t_latin = median_seconds(5, [&] { fields = scan(path); });
    std::printf("textio::CsvReader, every 10th line Latin-1: %zu fields, median %.3f s wall (%.3f s CPU), %.0f MB/s CPU\n",
                fields, t_latin.wall_s, t_latin.cpu_s, mb / t_latin.cpu_s);
#endif
    std::printf("load average after: %s\n", load_average().c_str());
    std::filesystem::remove(path);
    return 0;
}
