// The seed's experiment (seed 001, ch. 4): D 8 mm flat end mill, 2 flutes, 30 deg helix, radial
// depth 1 mm, axial depth 3 mm, 6000 mm/min at 10000 rpm (0.3 mm/tooth) on a 105 x 90 x 30 mm block,
// at 2 deg / 0.1 mm axial / 0.1 mm grid. Path: rapid approach, then a down-cut contour pass around
// the block (about 4.4 s of cutting). Prints the real-time factor (simulated machining seconds per
// wall second, median of several runs) for each device, their ratio, peak memory, the median time
// of each engine phase, the process CPU time per run (all threads; steadier than wall time on a
// shared machine) and the load average when the runs started.
#include "bench_util.hpp"
#include "force_model/engine_settings.hpp"
#include "kernels/opencl_runtime.hpp"
#include "motion_io/commanded.hpp"
#include "motion_io/nc_program.hpp"

#include <sys/resource.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

using namespace cutload;

using namespace cutload::bench;

namespace {

// The seed's finishing pass as a program, run at its commanded feed by motion_io's own commanded
// motion (the same path builder the "conventional" prediction uses).
constexpr const char* kContourProgram =
    "G21 G90 G54\n"
    "N5 G0 X-20 Y93 Z40 S10000 M03\n"   // tip 3 mm below the top at Z27; centre 3 mm outside: ae 1 mm
    "N10 G0 Z27\n"
    "N20 G1 X108 F6000\n"                // clockwise seen from above: down milling with M03
    "N30 Y-3\n"
    "N40 X-3\n"
    "N50 Y93\n"
    "N60 X20\n"
    "N70 G0 Z40\n";

motion_io::MotionModel contour_motion(const force_model::RunSpec& spec) {
    motion_io::NcReadOptions read;
    read.work_offsets_mm = motion_io::default_work_offsets(spec.offset_mm);
    const motion_io::NcProgram program = motion_io::parse_nc_program(kContourProgram, "bench contour", read);
    motion_io::CommandedOptions opt;
    opt.step_s = 0.001;
    opt.rapid_mm_min = 30000;
    return motion_io::commanded_motion(program, opt);
}

force_model::RunSpec seed_spec() {
    force_model::RunSpec s;
    s.tool.shape = force_model::ToolShape::Flat;
    s.tool.diameter_mm = 8;
    s.tool.flutes = 2;
    s.tool.helix_deg = 30;
    s.tool.flute_length_mm = 20;
    s.tool.stickout_mm = 30;
    s.tool.holder = {32, 40};
    s.material = {"Al7075-T6", 767.0, 168.8, 222.0, 27.7, 26.6, 0.7};
    s.stock.max_mm[0] = 105;
    s.stock.max_mm[1] = 90;
    s.stock.max_mm[2] = 30;
    s.offset_mm[0] = -200;
    s.offset_mm[1] = 300;
    s.offset_mm[2] = 350;
    s.resolution = {2, 0.1, 0.1};
    return s;
}

struct Result {
    bool ok = false;
    double rtf = 0, wall_s = 0, cpu_s = 0, peak_N = 0;
    std::size_t steps = 0, cutting = 0;
    std::string device;
    force_model::EnginePhases phases;   // medians
};

Result measure(const motion_io::MotionModel& m, const force_model::RunSpec& spec, force_model::Device d, int runs,
               bool keep_final_stock = false) {
    Result r;
    std::vector<double> walls, cpus;
    std::vector<force_model::EnginePhases> phases;
    try {
        for (int i = 0; i < runs; ++i) {
            force_model::PredictOptions o;
            o.device = d;
            o.keep_final_stock = keep_final_stock;
            force_model::EnginePhases ph;
            const double cpu0 = cpu_seconds();
            const auto p = force_model::predict_with(m, spec, o, force_model::EngineSettings{}, &ph);
            cpus.push_back(cpu_seconds() - cpu0);
            walls.push_back(p.stats.wall_s);
            phases.push_back(ph);
            r.steps = p.stats.steps;
            r.cutting = p.stats.cutting_steps;
            r.device = p.stats.device;
            r.peak_N = 0;
            for (const auto& b : p.blocks) r.peak_N = std::max(r.peak_N, b.peak_force_N);
            r.rtf = p.stats.simulated_s;
        }
    } catch (const std::exception& e) {
        std::printf("  %s: unavailable (%s)\n", d == force_model::Device::Cpu ? "cpu" : "opencl", e.what());
        return r;
    }
    r.wall_s = median(walls);
    r.cpu_s = median(cpus);
    r.rtf /= r.wall_s;
    using P = force_model::EnginePhases;
    for (double P::*f : {&P::setup_s, &P::walk_s, &P::queue_s, &P::wait_s, &P::rows_s, &P::removal_s, &P::holder_s,
                         &P::finish_s, &P::total_s}) {
        std::vector<double> v;
        for (const P& p : phases) v.push_back(p.*f);
        r.phases.*f = median(v);
    }
    r.phases.batches = phases.back().batches;
    r.phases.sweeps = phases.back().sweeps;
    r.ok = true;
    return r;
}

void print_phases(const force_model::EnginePhases& p) {
    std::printf("      phases (median ms): setup %.1f  walk %.1f  queue %.1f  wait %.1f  rows %.1f  removal %.1f  "
                "holder %.1f  finish %.1f  (total %.1f); %zu batches, %zu removal calls\n",
                1e3 * p.setup_s, 1e3 * p.walk_s, 1e3 * p.queue_s, 1e3 * p.wait_s, 1e3 * p.rows_s, 1e3 * p.removal_s,
                1e3 * p.holder_s, 1e3 * p.finish_s, 1e3 * p.total_s, p.batches, p.sweeps);
}

}  // namespace

// Usage: bench_force [RUNS] [opencl|cpu]
int main(int argc, char** argv) {
    const int runs = argc > 1 ? std::max(1, std::atoi(argv[1])) : 9;
    const auto spec = seed_spec();
    const auto m = contour_motion(spec);
    std::printf("bench_force: seed 001 experiment, contour pass, %.2f s of motion, resolution %.0f deg / %.1f mm / %.1f mm\n",
                m.t_s.back(), spec.resolution.angle_step_deg, spec.resolution.axial_step_mm, spec.resolution.grid_mm);
    std::printf("  load average at start: %s\n", load_average().c_str());
    const std::string only = argc > 2 ? argv[2] : "";   // "opencl" or "cpu": profile one path
    // Prediction after prediction in one process, as the service's workers run them, with the
    // service's allocator settings.
    if (!force_model::keep_freed_heap_for_next_prediction())
        std::printf("  (the allocator refused the service's thresholds: freed heap may be faulted in again)\n");
    const Result cl = only == "cpu" ? Result{} : measure(m, spec, force_model::Device::OpenCL, runs);
    const Result cpu = only == "opencl" ? Result{} : measure(m, spec, force_model::Device::Cpu, std::max(1, runs / 2 + 1));
    // What a caller that keeps the final stock (the service, --save-stock) pays on top: on a GPU,
    // reading back the tiles the run changed.
    const Result cl_kept = only == "cpu" ? Result{} : measure(m, spec, force_model::Device::OpenCL, runs, true);
    for (const Result* r : {&cl, &cpu, &cl_kept})
        if (r->ok) {
            if (r == &cl_kept) std::printf("  with the final stock kept (read back from the device):\n");
            std::printf("  %-40s median wall %.4f s  real-time factor %7.1fx  CPU %.4f s/run  (%zu steps, %zu cutting, "
                        "peak %.0f N)\n",
                        r->device.c_str(), r->wall_s, r->rtf, r->cpu_s, r->steps, r->cutting, r->peak_N);
            print_phases(r->phases);
        }
    if (cl.ok && cpu.ok) std::printf("  ratio opencl / cpu: %.2fx\n", cl.rtf / cpu.rtf);
    if (cl.ok) {
        // Every prediction after the first borrows the first one's queue, kernels and buffers.
        const kernels::PoolStats s = kernels::OpenClRuntime::instance().pool_stats();
        std::printf("  OpenCL objects over %d predictions: %zu queues, %zu kernels, %zu buffers created; %zu of %zu "
                    "leases reused\n",
                    2 * runs, s.queues_created, s.kernels_created, s.buffers_created, s.reused, s.leases);
    }
    std::printf("  peak memory (max RSS): %.0f MB\n", peak_rss_mb());
    std::printf("  load average at end: %s\n", load_average().c_str());
    return 0;
}
