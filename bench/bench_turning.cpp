// The simultaneous five-axis path (force_model::predict_turning on the multi-direction stock):
// a ball end mill D10 at 10 000 rpm, 2 deg per step, 0.1 mm cells and elements, 2 mm into a block,
// its lead turning from 5 to 25 deg (tilt 10 deg) while the tip runs 40 mm along X at 2000 mm/min;
// and the same pass at a fixed lean of 15 deg. Prints, per device (the OpenCL kernels and their
// scalar twins), the median wall and CPU time over the runs, the real-time factor, steps, peak
// force, the largest difference between the devices, peak memory and the load average, since the
// machine is shared.
#include "bench_util.hpp"
#include "force_model/force_model.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <tuple>
#include <cstdio>
#include <numbers>
#include <string>
#include <vector>

using namespace cutload;

namespace {

constexpr double kPi = std::numbers::pi;

const char* kSpec = R"json({
  "tool": {"shape": "ball", "diameter_mm": 10, "flutes": 2, "helix_deg": 30, "corner_radius_mm": 5,
           "flute_length_mm": 20, "stickout_mm": 30},
  "material": {"name": "Al7075-T6", "Ktc_N_mm2": 767.0, "Krc_N_mm2": 168.8, "Kac_N_mm2": 222.0,
               "Kte_N_mm": 27.7, "Kre_N_mm": 26.6, "Kae_N_mm": 0.7},
  "stock": {"box_mm": {"min": [0, -15, -20], "max": [40, 15, 0]}},
  "resolution": {"angle_step_deg": 2, "axial_step_mm": 0.1, "grid_mm": 0.1}
})json";

struct Pass {
    motion_io::MotionModel motion;
    force_model::ToolPoses poses;
};

// The tip from x = -8 to 42 at y 0, z -2, 1 ms samples; lead(t) from lead0 to lead1 over the pass.
Pass make_pass(double lead0_deg, double lead1_deg, double tilt_deg) {
    const double feed_mm_s = 2000.0 / 60, rpm = 10000, x0 = -8, x1 = 42, step_s = 0.001;
    const double duration_s = (x1 - x0) / feed_mm_s;
    const double dlead_rad_s = (lead1_deg - lead0_deg) * kPi / 180 / duration_s;
    const double tilt = tilt_deg * kPi / 180, ct = std::cos(tilt), st = std::sin(tilt);
    Pass p;
    motion_io::MotionModel& m = p.motion;
    m.step_s = step_s;
    m.block_names = {"N10"};
    const auto n = std::size_t(duration_s / step_s) + 1;
    for (std::size_t i = 0; i < n; ++i) {
        const double t = double(i) * step_s;
        m.t_s.push_back(t);
        m.x_mm.push_back(x0 + feed_mm_s * t);
        m.y_mm.push_back(0);
        m.z_mm.push_back(-2);
        m.vx_mm_s.push_back(feed_mm_s);
        m.vy_mm_s.push_back(0);
        m.vz_mm_s.push_back(0);
        m.spindle_rpm.push_back(rpm);
        m.spindle_angle_deg.push_back(6.0 * rpm * t);
        m.block.push_back(0);
        // R = Rx(tilt) Ry(lead): its columns are the tool's axes; the body rate is (0, dlead, 0).
        const double lead = (lead0_deg * kPi / 180) + dlead_rad_s * t, cl = std::cos(lead), sl = std::sin(lead);
        force_model::Rotation3 r;
        r.m = {cl, 0, sl, st * sl, ct, -st * cl, -ct * sl, st, ct * cl};
        p.poses.tool_to_stock.push_back(r);
        p.poses.omega_tool_rad_s.push_back({0, dlead_rad_s, 0});
    }
    m.session_start = {0};
    return p;
}

struct Measured {
    bench::Timing t;
    force_model::Prediction p;
};

Measured measure(const Pass& pass, const force_model::RunSpec& spec, force_model::Device d, int runs) {
    Measured out;
    force_model::PredictOptions opt;
    opt.device = d;
    opt.keep_final_stock = false;
    out.t = bench::median_seconds(runs, [&] { out.p = force_model::predict_turning(pass.motion, pass.poses, spec, opt); });
    return out;
}

double peak_N(const force_model::Prediction& p) {
    double peak = 0;
    for (const auto& s : p.samples) peak = std::max(peak, double(std::hypot(s.fx_N, s.fy_N, s.fz_N)));
    return peak;
}

}  // namespace

int main(int argc, char** argv) {
    const int runs = argc > 1 ? std::max(1, std::atoi(argv[1])) : 3;
    const force_model::RunSpec spec = force_model::parse_run_spec_text(kSpec, "bench_turning.json");
    std::printf("bench_turning: ball D10, 10000 rpm, 2 deg / 0.1 mm / 0.1 mm, 2 mm deep, 40 mm of block at 2000 mm/min; "
                "%d runs each\n",
                runs);
    std::printf("  load average at start: %s\n", bench::load_average().c_str());
    bool opencl = true;
    try {
        force_model::opencl_device_name();
    } catch (const std::exception& e) {
        opencl = false;
        std::printf("  no OpenCL device (%s): the twins only\n", e.what());
    }
    for (const auto& [name, lead0, lead1] : {std::tuple{"lead turning 5 -> 25 deg, tilt 10 deg", 5.0, 25.0},
                                            std::tuple{"fixed lean 15 deg, tilt 10 deg", 15.0, 15.0}}) {
        const Pass pass = make_pass(lead0, lead1, 10);
        const double simulated_s = pass.motion.t_s.back();
        std::printf("  %s (%.2f s of motion):\n", name, simulated_s);
        std::vector<Measured> got;
        for (force_model::Device d : {force_model::Device::Cpu, force_model::Device::OpenCL}) {
            if (d == force_model::Device::OpenCL && !opencl) continue;
            got.push_back(measure(pass, spec, d, runs));
            const Measured& m = got.back();
            std::printf("    %-60s median wall %7.3f s  real-time factor %6.3fx  CPU %7.3f s/run  (%zu steps, %zu cutting, "
                        "peak %.0f N)\n",
                        m.p.stats.device.c_str(), m.t.wall_s, simulated_s / m.t.wall_s, m.t.cpu_s, m.p.stats.steps,
                        m.p.stats.cutting_steps, peak_N(m.p));
        }
        if (got.size() == 2) {
            double worst = 0;
            const auto& a = got[0].p.samples;
            const auto& b = got[1].p.samples;
            for (std::size_t i = 0; i < std::min(a.size(), b.size()); ++i)
                worst = std::max(worst, double(std::hypot(a[i].fx_N - b[i].fx_N, a[i].fy_N - b[i].fy_N, a[i].fz_N - b[i].fz_N)));
            std::printf("    OpenCL / twins: %.2fx faster; largest force difference %.3g N (rows %zu / %zu)\n",
                        got[0].t.wall_s / got[1].t.wall_s, worst, a.size(), b.size());
        }
    }
    std::printf("  peak memory (max RSS): %.0f MB\n", bench::peak_rss_mb());
    std::printf("  load average at end: %s\n", bench::load_average().c_str());
    return 0;
}
