// The seed's experiment (seed 001, ch. 4): D 8 mm flat end mill, 2 flutes, 30 deg helix, radial
// depth 1 mm, axial depth 3 mm, 6000 mm/min at 10000 rpm (0.3 mm/tooth) on a 105 x 90 x 30 mm block,
// at 2 deg / 0.1 mm axial / 0.1 mm grid. Path: rapid approach, then a down-cut contour pass around
// the block (about 4.4 s of cutting). Prints the real-time factor (simulated machining seconds per
// wall second, median of several runs) for each device, their ratio, peak memory, the median time
// of each engine phase, the process CPU time per run (all threads; steadier than wall time on a
// shared machine) and the load average when the runs started.
#include "force_model/engine.hpp"

#include <sys/resource.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

using namespace cutload;

namespace {

using P3 = std::array<double, 3>;

struct Leg {
    P3 end;
    double feed_mm_min;
    std::string block;
};

motion_io::MotionModel contour_motion() {
    const double step_s = 0.001, rpm = 10000;
    const double z = 27, off = 3;   // tip 3 mm below the top; centre 3 mm outside: 1 mm radial depth
    const P3 start{-20, 90 + off, 40};
    // Clockwise around the block seen from above: down milling with an M03 right-hand cutter.
    const std::vector<Leg> legs{
        {{-20, 90 + off, z}, 30000, "N10 G0 Z27"},
        {{105 + off, 90 + off, z}, 6000, "N20 G1 X108 F6000"},
        {{105 + off, -off, z}, 6000, "N30 G1 Y-3"},
        {{-off, -off, z}, 6000, "N40 G1 X-3"},
        {{-off, 90 + off, z}, 6000, "N50 G1 Y93"},
        {{20, 90 + off, z}, 6000, "N60 G1 X20"},
        {{20, 90 + off, 40}, 30000, "N70 G0 Z40"},
    };
    motion_io::MotionModel m;
    m.step_s = step_s;
    double t = 0, angle = 0;
    P3 p = start;
    auto push = [&](const P3& pos, const P3& v, int block) {
        if (!m.t_s.empty()) angle += 6.0 * rpm * step_s;
        m.t_s.push_back(t);
        m.x_mm.push_back(pos[0] + 200);   // machine coordinates: work zero at X200 Y-300 Z-350
        m.y_mm.push_back(pos[1] - 300);
        m.z_mm.push_back(pos[2] - 350);
        m.vx_mm_s.push_back(v[0]);
        m.vy_mm_s.push_back(v[1]);
        m.vz_mm_s.push_back(v[2]);
        m.spindle_rpm.push_back(rpm);
        m.spindle_angle_deg.push_back(angle);
        m.block.push_back(block);
        t += step_s;
    };
    for (std::size_t l = 0; l < legs.size(); ++l) {
        m.block_names.push_back(legs[l].block);
        const P3 d{legs[l].end[0] - p[0], legs[l].end[1] - p[1], legs[l].end[2] - p[2]};
        const double len = std::hypot(d[0], d[1], d[2]), speed = legs[l].feed_mm_min / 60;
        const long n = std::max(1L, std::lround(len / (speed * step_s)));
        const P3 v{d[0] / len * speed, d[1] / len * speed, d[2] / len * speed};
        for (long k = 0; k < n; ++k) {
            const double u = double(k) / double(n);
            push({p[0] + u * d[0], p[1] + u * d[1], p[2] + u * d[2]}, v, int(l));
        }
        p = legs[l].end;
    }
    push(p, {0, 0, 0}, int(legs.size()) - 1);
    m.session_start = {0};
    return m;
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

double peak_rss_mb() {
    rusage u{};
    getrusage(RUSAGE_SELF, &u);
    return double(u.ru_maxrss) / 1024.0;
}

double cpu_seconds() {
    rusage u{};
    getrusage(RUSAGE_SELF, &u);
    return double(u.ru_utime.tv_sec + u.ru_stime.tv_sec) + 1e-6 * double(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

std::string load_average() {
    std::ifstream in("/proc/loadavg");
    std::string one, five, fifteen;
    in >> one >> five >> fifteen;
    return one.empty() ? "unknown" : one + " " + five + " " + fifteen;
}

double median(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v.empty() ? 0.0 : v[v.size() / 2];
}

struct Result {
    bool ok = false;
    double rtf = 0, wall_s = 0, cpu_s = 0, peak_N = 0;
    std::size_t steps = 0, cutting = 0;
    std::string device;
    force_model::EnginePhases phases;   // medians
};

Result measure(const motion_io::MotionModel& m, const force_model::RunSpec& spec, force_model::Device d, int runs) {
    Result r;
    std::vector<double> walls, cpus;
    std::vector<force_model::EnginePhases> phases;
    try {
        for (int i = 0; i < runs; ++i) {
            force_model::PredictOptions o;
            o.device = d;
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
    const auto m = contour_motion();
    const auto spec = seed_spec();
    std::printf("bench_force: seed 001 experiment, contour pass, %.2f s of motion, resolution %.0f deg / %.1f mm / %.1f mm\n",
                m.t_s.back(), spec.resolution.angle_step_deg, spec.resolution.axial_step_mm, spec.resolution.grid_mm);
    std::printf("  load average at start: %s\n", load_average().c_str());
    const std::string only = argc > 2 ? argv[2] : "";   // "opencl" or "cpu": profile one path
    const Result cl = only == "cpu" ? Result{} : measure(m, spec, force_model::Device::OpenCL, runs);
    const Result cpu = only == "opencl" ? Result{} : measure(m, spec, force_model::Device::Cpu, std::max(1, runs / 2 + 1));
    for (const Result* r : {&cl, &cpu})
        if (r->ok) {
            std::printf("  %-40s median wall %.4f s  real-time factor %7.1fx  CPU %.4f s/run  (%zu steps, %zu cutting, "
                        "peak %.0f N)\n",
                        r->device.c_str(), r->wall_s, r->rtf, r->cpu_s, r->steps, r->cutting, r->peak_N);
            print_phases(r->phases);
        }
    if (cl.ok && cpu.ok) std::printf("  ratio opencl / cpu: %.2fx\n", cl.rtf / cpu.rtf);
    std::printf("  peak memory (max RSS): %.0f MB\n", peak_rss_mb());
    std::printf("  load average at end: %s\n", load_average().c_str());
    return 0;
}
