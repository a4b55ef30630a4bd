// What a tool table costs: the second demo (data/demo2_*: a face mill, an end mill with a pocket,
// a drill with a pecking cycle; 72 s of dry run with its tool column) predicted
//   A. with its tool table (three cutters, switched at each tool change),
//   B. with one tool for every sample (the end mill T2 as the run's `tool`, no table, the log's tool
//      channel dropped: the run as it was before tool tables), and
//   C. with a table of three entries that are all that end mill: B's physics with A's switching,
// so C / B is the cost of the switching itself (tool plan, the flush and removal at each change,
// per-tool tables) and A / B what the real tools change (a 50.8 mm face mill and a drill cut other
// material than the end mill would). The runs take turns (A B C A B C ...). Prints the median wall
// and CPU time of each, the ratios, the angle steps and the load average (the machine is shared:
// CPU time per run is the steadier figure).
#include "bench_util.hpp"
#include "force_model/engine_settings.hpp"
#include "force_model/force_model.hpp"
#include "motion_io/motion_io.hpp"

#include <sys/resource.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>
#include <vector>

using namespace cutload;

using namespace cutload::bench;

namespace {

struct Result {
    double wall_s = 0, cpu_s = 0, setup_s = 0;
    std::size_t steps = 0, cutting = 0, unknown = 0;
    double removed_mm3 = 0;
    std::string device;
};

// One run of each configuration in turn, `runs` times, so a change of load on the shared machine
// falls on all of them alike; medians per configuration.
struct Config {
    const motion_io::MotionModel* motion;
    const force_model::RunSpec* spec;
    std::vector<double> walls, cpus, setups;
    Result r;
};

void measure(std::vector<Config>& configs, force_model::Device d, int runs) {
    for (int i = 0; i < runs; ++i)
        for (Config& c : configs) {
            force_model::PredictOptions o;
            o.device = d;
            force_model::EnginePhases ph;
            const double cpu0 = cpu_seconds();
            const auto p = force_model::predict_with(*c.motion, *c.spec, o, force_model::EngineSettings{}, &ph);
            c.cpus.push_back(cpu_seconds() - cpu0);
            c.walls.push_back(p.stats.wall_s);
            c.setups.push_back(ph.setup_s);
            c.r.steps = p.stats.steps;
            c.r.cutting = p.stats.cutting_steps;
            c.r.unknown = p.stats.unknown_tool_samples;
            c.r.device = p.stats.device;
            c.r.removed_mm3 = 0;
            for (const auto& b : p.blocks) c.r.removed_mm3 += b.removed_mm3;
        }
    for (Config& c : configs) {
        c.r.wall_s = median(c.walls);
        c.r.cpu_s = median(c.cpus);
        c.r.setup_s = median(c.setups);
    }
}

void print(const char* name, const Result& r) {
    std::printf("  %-44s median wall %7.3f s  CPU %7.3f s/run  setup %6.1f ms  (%zu steps, %zu cutting, %.0f mm3 removed, "
                "%zu samples of unknown tools)\n",
                name, r.wall_s, r.cpu_s, 1e3 * r.setup_s, r.steps, r.cutting, r.removed_mm3, r.unknown);
}

}  // namespace

// Usage: bench_tools [RUNS] [cpu|opencl] [GRID_MM]   (GRID_MM also sets the axial step; default: the spec's)
int main(int argc, char** argv) {
    const int runs = argc > 1 ? std::max(1, std::atoi(argv[1])) : 3;
    const std::string device = argc > 2 ? argv[2] : "cpu";
    const force_model::Device d = device == "opencl" ? force_model::Device::OpenCL : force_model::Device::Cpu;
    const std::string dir = std::string(CUTLOAD_SOURCE_DIR) + "/data/";

    force_model::RunSpec table = force_model::load_run_spec(dir + "demo2_run.json");
    if (argc > 3) table.resolution.grid_mm = table.resolution.axial_step_mm = std::atof(argv[3]);
    const motion_io::MotionModel m = motion_io::ingest(dir + "demo2_dryrun.csv", motion_io::ReadOptions{});

    // B: the end mill for every sample.
    const force_model::NumberedTool* end_mill = force_model::find_tool(table, 2);
    if (!end_mill) {
        std::fprintf(stderr, "bench_tools: data/demo2_run.json has no T2\n");
        return 1;
    }
    force_model::RunSpec one = table;
    one.tools.clear();
    one.has_tool = true;
    one.tool = end_mill->tool;
    // C: the table's numbers, every entry the end mill.
    force_model::RunSpec same = table;
    for (auto& t : same.tools) t.tool = end_mill->tool;

    std::size_t changes = 0;
    for (std::size_t i = 1; i < m.tool.size(); ++i) changes += m.tool[i] != m.tool[i - 1];
    std::printf("bench_tools: demo2, %.1f s of motion, %zu samples, %zu tool changes in the log; resolution %.1f deg / %.2f mm / "
                "%.2f mm; %d runs each on %s\n",
                m.t_s.back() - m.t_s.front(), m.size(), changes, table.resolution.angle_step_deg, table.resolution.axial_step_mm,
                table.resolution.grid_mm, runs, device.c_str());
    std::printf("  load average at start: %s\n", load_average().c_str());
    motion_io::MotionModel untooled = m;
    untooled.tool.clear();
    std::vector<Config> configs(3);
    configs[0].motion = &m, configs[0].spec = &table;
    configs[1].motion = &untooled, configs[1].spec = &one;
    configs[2].motion = &m, configs[2].spec = &same;
    measure(configs, d, runs);
    const Result &a = configs[0].r, &b = configs[1].r, &c = configs[2].r;
    std::printf("  device: %s\n", a.device.c_str());
    print("A tool table (face mill, end mill, drill)", a);
    print("B one tool (the end mill) for every sample", b);
    print("C table of three, each the end mill", c);
    std::printf("  switching cost C / B: wall %.3fx, CPU %.3fx; real tools A / B: wall %.3fx, CPU %.3fx\n", c.wall_s / b.wall_s,
                c.cpu_s / b.cpu_s, a.wall_s / b.wall_s, a.cpu_s / b.cpu_s);
    std::printf("  load average at end: %s\n", load_average().c_str());
    return 0;
}
