// Cost of the machine kinematics a five-axis engine will call per step: forward kinematics
// (nominal and with the example error set), the tool axis and bed frame a machine-axis prediction row
// needs (two walks of the chain, or forward_with_bed's one), inverse kinematics, the interval twist.
// Prints the median time per call over several runs, the calls per second, what that means at
// the engine's step rate (10000 rpm at 2 deg per step: 30000 steps per second of motion), and the
// load average, since the machine is shared.
#include "machine/kinematics.hpp"
#include "machine/machine.hpp"
#include "machine/twist.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

using namespace cutload::machine;

namespace {

std::string load_average() {
    std::ifstream in("/proc/loadavg");
    std::string a, b, c;
    in >> a >> b >> c;
    return a + " " + b + " " + c;
}

// Median over `runs` of the time per call of f(i), i = 0..calls-1.
template <class F>
double median_ns_per_call(int runs, int calls, F&& f) {
    std::vector<double> per_call;
    for (int r = 0; r < runs; ++r) {
        const auto t0 = std::chrono::steady_clock::now();
        for (int i = 0; i < calls; ++i) f(i);
        per_call.push_back(std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - t0).count() / calls);
    }
    std::sort(per_call.begin(), per_call.end());
    return per_call[per_call.size() / 2];
}

volatile double g_sink = 0;   // keeps the results alive

}  // namespace

int main(int argc, char** argv) {
    const std::string root = argc > 1 ? argv[1] : CUTLOAD_SOURCE_DIR;
    Machine nominal = load_machine(root + "/data/machines/ac_table_table.json");
    Machine with_errors = nominal;
    load_errors(with_errors, root + "/data/machines/ac_table_table_errors.json");
    const int calls = 200000, runs = 9;
    std::printf("load average before: %s\n", load_average().c_str());

    // A smooth five-axis move sampled at 1 ms.
    std::vector<AxisPositions> q(calls);
    for (int i = 0; i < calls; ++i) {
        const double t = i * 1e-3;
        q[i] = positions(nominal, {{'X', -350 + 100 * std::sin(t)}, {'Y', -275 + 80 * std::cos(0.7 * t)},
                                   {'Z', -200 + 20 * std::sin(1.3 * t)}, {'A', -45 + 40 * std::sin(0.2 * t)},
                                   {'C', 30 * t}});
    }
    std::vector<ToolPose> poses(calls);
    const double fk = median_ns_per_call(runs, calls, [&](int i) { poses[i] = forward(nominal, q[i], 120, ErrorMode::Nominal); });
    const double fk_err = median_ns_per_call(runs, calls, [&](int i) { g_sink = g_sink + forward(with_errors, q[i], 120).tip_mm().x(); });
    // What a prediction row with machine axes needs (app::MachineAxesForces): the tool axis and the
    // bed frame, once as two walks of the chain and once as one.
    const double fk_bed_two = median_ns_per_call(runs, calls, [&](int i) {
        g_sink = g_sink + forward(with_errors, q[i], 0).axis().x() + bed_to_workpiece(with_errors, q[i]).R(0, 1);
    });
    const double fk_bed_one = median_ns_per_call(runs, calls, [&](int i) {
        const ToolAndBed both = forward_with_bed(with_errors, q[i], 0);
        g_sink = g_sink + both.tool.axis().x() + both.bed_to_workpiece.R(0, 1);
    });
    const double ik = median_ns_per_call(runs, calls / 4, [&](int i) {
        const int k = i + 1;
        g_sink = g_sink + inverse(nominal, poses[k].tip_mm(), poses[k].axis(), 120, q[k - 1]).value[0];
    });
    const double tw = median_ns_per_call(runs, calls - 1, [&](int i) {
        g_sink = g_sink + interval_twist(poses[i].tool_to_workpiece, poses[i + 1].tool_to_workpiece, 1e-3).v_mm_s.x();
    });
    const double steps_per_s = 30000;   // 10000 rpm, 2 deg per step
    std::printf("forward, nominal:        %7.0f ns/call  %6.2f M/s  %5.2f %% of one core at %.0f steps/s\n", fk, 1e3 / fk,
                100 * fk * 1e-9 * steps_per_s, steps_per_s);
    std::printf("forward, with errors:    %7.0f ns/call  %6.2f M/s  %5.2f %%\n", fk_err, 1e3 / fk_err, 100 * fk_err * 1e-9 * steps_per_s);
    std::printf("forward + bed, 2 walks:  %7.0f ns/call  %6.2f M/s  %5.2f %%  (with errors)\n", fk_bed_two, 1e3 / fk_bed_two,
                100 * fk_bed_two * 1e-9 * steps_per_s);
    std::printf("forward_with_bed:        %7.0f ns/call  %6.2f M/s  %5.2f %%  (with errors)\n", fk_bed_one, 1e3 / fk_bed_one,
                100 * fk_bed_one * 1e-9 * steps_per_s);
    std::printf("inverse (nearest):       %7.0f ns/call  %6.2f M/s\n", ik, 1e3 / ik);
    std::printf("interval twist:          %7.0f ns/call  %6.2f M/s  %5.2f %%\n", tw, 1e3 / tw, 100 * tw * 1e-9 * steps_per_s);
    std::printf("load average after: %s\n", load_average().c_str());
    return 0;
}
