#include "app/path_dry_run.hpp"

#include "machine/kinematics.hpp"
#include "motion_io/nc_program.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <iterator>
#include <numbers>
#include <stdexcept>

namespace cutload::app {

namespace {

// Program words carry 6 decimals: far below the posts' 0.001 mm and 0.001 deg.
std::string word(char letter, double value) {
    const double v = std::round(value * 1e6) / 1e6;
    return fmt::format("{}{:.6f}", letter, v == 0 ? 0.0 : v);   // no "-0.000000"
}

}  // namespace

PathDryRun synthesize_path_dry_run(const PathDryRunSpec& spec, const machine::Machine& machine, std::ostream& csv) {
    if (!spec.path) throw std::invalid_argument("path dry run: no path");
    if (!(spec.duration_s > 0) || !(spec.idle_before_s >= 0) || !(spec.idle_after_s >= 0))
        throw std::invalid_argument("path dry run: the duration must be > 0 and the idle stretches >= 0");
    const double T = spec.machine.cnc_period_s;
    if (!(T > 0)) throw std::invalid_argument("path dry run: the CNC period must be > 0");
    // The log's columns are the axes' letters (x, y, z, a, b, c): the machine must read those.
    for (const machine::Axis& a : machine.chain)
        if (!a.channel.empty() && (a.channel.size() != 1 || std::tolower(static_cast<unsigned char>(a.channel[0])) !=
                                                                 std::tolower(static_cast<unsigned char>(a.name))))
            throw std::invalid_argument(fmt::format("path dry run: axis {} reads channel '{}', but the generated log names "
                                                    "its column after the axis",
                                                    a.name, a.channel));

    // The joint-space points, one per interpolation period, each nearest the one before.
    const auto pieces = std::max<std::size_t>(1, std::size_t(std::ceil(spec.duration_s / T - 1e-9)));
    const double piece_s = spec.duration_s / double(pieces);
    machine::AxisPositions previous = machine::positions(machine, spec.start_axes);
    std::vector<machine::AxisPositions> points;
    points.reserve(pieces + 1);
    for (std::size_t k = 0; k <= pieces; ++k) {
        const PathPose p = spec.path(spec.duration_s * double(k) / double(pieces));
        const Eigen::Vector3d tip(p.tip_mm[0], p.tip_mm[1], p.tip_mm[2]);
        const Eigen::Vector3d axis = Eigen::Vector3d(p.axis[0], p.axis[1], p.axis[2]).normalized();
        previous = machine::inverse(machine, tip, axis, spec.tool_length_mm, previous);
        points.push_back(previous);
    }

    // The program in machine-axis form: machine coordinates (G54 at 0), the spindle on from the
    // start, a dwell, then every piece in G93 (1/F minutes each) under one sequence number.
    PathDryRun out;
    out.block = "N30";
    auto words = [&](const machine::AxisPositions& q) {
        std::string w;
        for (std::size_t i = 0; i < machine.chain.size(); ++i) {
            w += ' ';
            w += word(machine.chain[i].name, q.value[i]);
        }
        return w;
    };
    std::string& text = out.program;
    text += "%\n";
    text += fmt::format("(CUTLOAD PATH DRY RUN: {} PIECES OF {:.6f} S IN MACHINE-AXIS FORM, ONE PER INTERPOLATION PERIOD)\n",
                        pieces, piece_s);
    text += fmt::format("N10 G21 G90 G94 G54 S{:.0f} M03\n", spec.spindle_rpm);
    if (spec.idle_before_s > 0) text += fmt::format("N20 G04 X{:.6f}\n", spec.idle_before_s);
    std::string last = words(points.front());
    for (std::size_t k = 1; k <= pieces; ++k) {
        const std::string w = words(points[k]);
        // A piece that moves no axis would have no length to time: the machine stands for it.
        if (w == last)
            text += fmt::format("{} G04 X{:.6f}\n", out.block, piece_s);
        else
            text += fmt::format("{} G93 G01{} F{:.6f}\n", out.block, w, 60.0 / piece_s);
        last = w;
    }
    text += "N40 G94\nN50 M30\n%\n";

    motion_io::NcReadOptions ro;
    ro.work_offsets_mm["G54"] = {0, 0, 0};
    ro.rotary_axes.clear();
    std::array<double, 3> start_mm{}, start_deg{};
    for (std::size_t i = 0; i < machine.chain.size(); ++i) {
        const machine::Axis& a = machine.chain[i];
        const double v = std::round(points.front().value[i] * 1e6) / 1e6;
        if (a.rotary()) {
            ro.rotary_axes += a.name;
            start_deg[std::size_t(a.name - 'A')] = v;
        } else {
            start_mm[std::size_t(a.name - 'X')] = v;
        }
    }
    std::sort(ro.rotary_axes.begin(), ro.rotary_axes.end());
    ro.start_mm = start_mm;
    ro.start_deg = start_deg;

    motion_io::NcDryRunSpec run;
    run.program = motion_io::parse_nc_program(text, "path_dry_run.nc", ro);
    std::copy(start_mm.begin(), start_mm.end(), run.start_mm);
    std::copy(start_deg.begin(), start_deg.end(), run.start_deg);
    run.machine = spec.machine;
    run.machine.max_accel_mm_s2 = 0;   // the path's own timing; acc/dec after interpolation only
    run.client = spec.client;
    run.settle_s = spec.idle_after_s;
    run.seed = spec.seed;
    out.rows = motion_io::synthesize_nc_dry_run(run, csv);

    out.path_start_s = spec.idle_before_s;
    const double n1 = std::max(spec.machine.accdec_ticks[0], 1), n2 = std::max(spec.machine.accdec_ticks[1], 1);
    const double k = spec.machine.servo_time_constant_s > 0 ? 1.0 - std::exp(-T / spec.machine.servo_time_constant_s) : 1.0;
    out.lag_s = (n1 - 1) * T / 2 + (n2 - 1) * T / 2 + T * (1 - k) / k;
    return out;
}

PathDryRunSpec doc000_case_spec() {
    PathDryRunSpec s;
    s.path = [](double t) {
        const double theta = 2 * std::numbers::pi * t / 9, c = std::cos(theta), sn = std::sin(theta);
        PathPose p;
        p.tip_mm = {kDoc000OriginMm[0], kDoc000OriginMm[1] + 10 * t * c + (20 - 20 * t) * sn,
                    kDoc000OriginMm[2] + (20 * t - 20) * c + 10 * t * sn};
        p.axis = {0, -sn, c};
        return p;
    };
    s.duration_s = 1;
    s.tool_length_mm = kDoc000ToolLengthMm;
    // The branch A = -theta, C = 180 deg: A = +theta with C = 0 would pass A's upper limit of 30 deg
    // at t = 0.75 s, and the controller would have to turn C half a turn mid-path.
    s.start_axes = {{'A', 0}, {'C', 180}};
    s.spindle_rpm = 6000;
    s.idle_before_s = 0.5;
    s.idle_after_s = 0.5;
    s.seed = 20250420;
    return s;
}

}  // namespace cutload::app
