// The stock round trip a run with a base run makes in the service: the final stock saved, then
// loaded as the next run's base stock. In bytes (what the service does now: the database holds
// the bytes) against through a file (what it did before: save to a file, read it back into the
// database; write the blob to a temporary file, load that). Stock: the demo's final one (CPU
// prediction of data/demo_dryrun.csv). Prints its size, the medians of 7 runs (wall and CPU) and
// the load average, since the machine is shared.
#include "app/predict_run.hpp"
#include "force_model/stock.hpp"   // the grid size printed (bench sees internals)

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <sys/resource.h>
#include <unistd.h>

using namespace cutload;

namespace {

double cpu_seconds() {
    rusage u{};
    getrusage(RUSAGE_SELF, &u);
    return static_cast<double>(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
           1e-6 * static_cast<double>(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

struct Timing {
    double wall_ms, cpu_ms;   // medians
};

template <class F>
Timing median_ms(int runs, F&& f) {
    std::vector<double> wall, cpu;
    for (int i = 0; i < runs; ++i) {
        const auto t0 = std::chrono::steady_clock::now();
        const double c0 = cpu_seconds();
        f();
        cpu.push_back(1e3 * (cpu_seconds() - c0));
        wall.push_back(1e3 * std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    }
    std::sort(wall.begin(), wall.end());
    std::sort(cpu.begin(), cpu.end());
    return {wall[wall.size() / 2], cpu[cpu.size() / 2]};
}

std::string read_bytes(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

}  // namespace

int main() {
    const std::string root = CUTLOAD_SOURCE_DIR;
    app::RunInput in;
    in.log_path = root + "/data/demo_dryrun.csv";
    in.spec = force_model::load_run_spec(root + "/data/demo_run.json");
    const app::RunResult r = app::predict_run(in);
    const force_model::Stock& stock = *r.prediction.final_stock;
    const std::string dir = std::filesystem::temp_directory_path() / ("cutload_bench_stock_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir);

    std::string blob;
    const Timing save_bytes = median_ms(7, [&] { blob = force_model::save_stock_bytes(stock); });
    const Timing load_bytes = median_ms(7, [&] { force_model::load_stock_bytes(blob, "stock"); });
    const Timing save_file = median_ms(7, [&] {
        force_model::save_stock(stock, dir + "/final.stock");
        blob = read_bytes(dir + "/final.stock");
        std::filesystem::remove(dir + "/final.stock");
    });
    const Timing load_file = median_ms(7, [&] {
        std::ofstream(dir + "/base.stock", std::ios::binary).write(blob.data(), static_cast<std::streamsize>(blob.size()));
        force_model::load_stock(dir + "/base.stock");
        std::filesystem::remove(dir + "/base.stock");
    });
    std::filesystem::remove_all(dir);

    double load[3] = {0, 0, 0};
    getloadavg(load, 3);
    std::printf("demo final stock: %zu x %zu rays, %.1f MB\n", std::size_t(stock.grid.nx), std::size_t(stock.grid.ny),
                double(blob.size()) / 1e6);
    std::printf("%-34s %10s %10s\n", "median of 7", "wall ms", "cpu ms");
    std::printf("%-34s %10.1f %10.1f\n", "save to bytes", save_bytes.wall_ms, save_bytes.cpu_ms);
    std::printf("%-34s %10.1f %10.1f\n", "save to a file, read back", save_file.wall_ms, save_file.cpu_ms);
    std::printf("%-34s %10.1f %10.1f\n", "load from bytes", load_bytes.wall_ms, load_bytes.cpu_ms);
    std::printf("%-34s %10.1f %10.1f\n", "write a temporary file, load it", load_file.wall_ms, load_file.cpu_ms);
    std::printf("round trip: bytes %.1f ms, files %.1f ms (wall; ratio %.2f); load average %.2f %.2f %.2f\n",
                save_bytes.wall_ms + load_bytes.wall_ms, save_file.wall_ms + load_file.wall_ms,
                (save_file.wall_ms + load_file.wall_ms) / (save_bytes.wall_ms + load_bytes.wall_ms), load[0], load[1], load[2]);
}
