// What a user waits for per command: the built `cutload` binary run end to end (process start,
// ingest, prediction, FORCES.csv), fork/exec'd several times. Prints the medians of the wall time
// and of the child's CPU time (user + system; steadier than wall time on a shared machine) for
//   - `cutload inspect` of a short log (200 rows of the first demo's machine and client),
//   - `cutload predict` of a ~10 s contour log (the seed's finishing pass, two levels) on
//     --device cpu and --device opencl (one untimed run first, so PoCL's kernel cache is warm),
// with the load average before and after. Both logs come from motion_io's seeded generators
// (motion_io/synth.hpp) and are written to a temporary folder that is removed at the end.
//
// Usage: bench_startup [RUNS] [PATH/TO/cutload]   (default 7 runs, ../cli/cutload beside this program)
// CUTLOAD_BENCH_KEEP=1 keeps the generated logs (their folder is printed).
#include "bench_util.hpp"
#include "motion_io/nc_program.hpp"
#include "motion_io/synth.hpp"

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

using namespace cutload;
using namespace cutload::bench;
namespace fs = std::filesystem;

namespace {

// The seed's finishing pass (radial 1 mm, axial 3 mm, F6000, S10000 M03, down cut) around the
// demo stock, at two levels: about 10 s of motion, rapids included.
constexpr const char* kContourProgram =
    "G21 G90 G54\n"
    "N5 G0 X-20 Y93 Z40 S10000 M03\n"
    "N10 G0 Z27\n"
    "N20 G1 X108 F6000\n"
    "N30 Y-3\n"
    "N40 X-3\n"
    "N50 Y93\n"
    "N60 X20\n"
    "N70 G0 Z40\n"
    "N80 G0 X-20\n"
    "N90 G0 Z24\n"
    "N100 G1 X108 F6000\n"
    "N110 Y-3\n"
    "N120 X-3\n"
    "N130 Y93\n"
    "N140 X20\n"
    "N150 G0 Z40\n";

struct Logs {
    fs::path short_log, contour_log;
    std::size_t short_rows = 0, contour_rows = 0;
};

Logs write_logs(const fs::path& dir) {
    Logs logs;
    logs.short_log = dir / "short.csv";
    logs.contour_log = dir / "contour.csv";
    {
        motion_io::DryRunSpec spec = motion_io::demo_dry_run_spec();
        spec.max_rows = 200;
        std::ofstream out(logs.short_log, std::ios::binary);
        logs.short_rows = motion_io::synthesize_dry_run(spec, out);
    }
    {
        motion_io::NcReadOptions read;
        // Work zero at the demo's machine position of the stock corner (data/demo_run.json).
        const double setup_offset_mm[3] = {-200, 300, 350};
        read.work_offsets_mm = motion_io::default_work_offsets(setup_offset_mm);
        motion_io::NcDryRunSpec spec;
        spec.program = motion_io::parse_nc_program(kContourProgram, "bench contour", read);
        const double start[3] = {180, -207, -310};
        std::copy(start, start + 3, spec.start_mm);
        spec.machine.max_accel_mm_s2 = 2500;
        spec.seed = 20261123;
        std::ofstream out(logs.contour_log, std::ios::binary);
        logs.contour_rows = motion_io::synthesize_nc_dry_run(spec, out);
    }
    return logs;
}

// Median wall and CPU time of `runs` runs after `warmup` untimed ones; false when any run fails.
bool measure(const char* label, const std::vector<std::string>& args, int runs, int warmup) {
    for (int i = 0; i < warmup; ++i)
        if (run_child(args).status != 0) {
            std::printf("  %-34s failed (exit status non-zero): %s\n", label, args[1].c_str());
            return false;
        }
    std::vector<double> wall, cpu;
    for (int i = 0; i < runs; ++i) {
        const ChildRun r = run_child(args);
        if (r.status != 0) {
            std::printf("  %-34s failed (exit status %d)\n", label, r.status);
            return false;
        }
        wall.push_back(r.wall_s);
        cpu.push_back(r.cpu_s);
    }
    std::printf("  %-34s median wall %7.1f ms   median CPU %7.1f ms   (%d runs)\n", label, 1e3 * median(wall),
                1e3 * median(cpu), runs);
    return true;
}

}  // namespace

int main(int argc, char** argv) {
    const int runs = argc > 1 ? std::max(1, std::atoi(argv[1])) : 7;
    const fs::path self = fs::canonical("/proc/self/exe");
    const std::string cutload = argc > 2 ? std::string(argv[2]) : (self.parent_path().parent_path() / "cli" / "cutload").string();
    if (!fs::exists(cutload)) {
        std::fprintf(stderr, "bench_startup: %s not found (build the cutload target, or pass its path)\n", cutload.c_str());
        return 1;
    }
    const std::string run_spec = std::string(CUTLOAD_SOURCE_DIR) + "/data/demo_run.json";
    char tmpl[] = "/tmp/cutload_bench_startup_XXXXXX";
    if (mkdtemp(tmpl) == nullptr) {
        std::perror("bench_startup: mkdtemp");
        return 1;
    }
    const fs::path dir = tmpl;
    const Logs logs = write_logs(dir);
    const std::string forces = (dir / "FORCES.csv").string();

    std::printf("bench_startup: %s, load average %s\n", cutload.c_str(), load_average().c_str());
    std::printf("  logs: short %zu rows (first demo's machine/client), contour %zu rows (seed finishing pass, 2 levels)\n",
                logs.short_rows, logs.contour_rows);
    bool ok = measure("inspect, short log", {cutload, "inspect", logs.short_log.string()}, runs, 1);
    for (const char* device : {"cpu", "opencl"}) {
        const std::string label = std::string("predict, 10 s contour, --device ") + device;
        ok = measure(label.c_str(),
                     {cutload, "predict", "-q", "--device", device, "--spec", run_spec, "--out", forces,
                      logs.contour_log.string()},
                     runs, 1) && ok;
    }
    std::printf("  load average after: %s\n", load_average().c_str());
    if (std::getenv("CUTLOAD_BENCH_KEEP") == nullptr) fs::remove_all(dir);
    else std::printf("  logs kept in %s\n", dir.c_str());
    return ok ? 0 : 1;
}
