// Dry-run logs of a tool path given against the part, as a five-axis machine records it
// (docs/five_axis.md, section 8): the tool tip and axis in workpiece coordinates as functions of
// time go through the machine's inverse kinematics on its nominal chain, and the axes so found run
// on motion_io/synth's machine and client, which write the log.
//
// How the machine runs the path: as a controller in tool-centre-point mode does, it works out the
// axes once per interpolation period (inverse kinematics, nominal chain, the solution nearest the
// previous one within limits) and moves every axis linearly between those points; then each axis
// goes through the acceleration/deceleration after interpolation and the servo lag of
// motion_io::MachineModel, the CNC latches the actual axes every period, and the client reads them
// in its unequal cycle with quantised posts (motion_io::ClientModel). The joint-space points are
// handed to the synth as a program in machine-axis form (one G93 G01 piece per period, all named
// by one sequence number), so the log is what synthesize_nc_dry_run writes for that program:
// columns t_spindle, spindle, t_feed, feed, t_pos, x, y, z, then one per rotary axis of the
// machine, tool, block.
//
// Why here: motion_io (the synth) must not know machines, and machine/ knows no logs; the
// application has both.
#pragma once

#include "machine/machine.hpp"
#include "motion_io/synth.hpp"

#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <ostream>
#include <string>

namespace cutload::app {

// The tool at one instant, in workpiece coordinates (docs/machines.md: fixed to the table,
// coinciding with the machine's home coordinates when every axis is at 0): the tip, and the unit
// tool axis from the tip toward the spindle.
struct PathPose {
    std::array<double, 3> tip_mm{};
    std::array<double, 3> axis{0, 0, 1};
};

struct PathDryRunSpec {
    // The path at path time u in [0, duration_s].
    std::function<PathPose(double u_s)> path;
    double duration_s = 1;
    double tool_length_mm = 0;                // gauge point to tip
    // Axis positions (letters; deg for rotary axes) the inverse kinematics starts from: of the
    // solutions of the first pose, the one nearest these. This picks the machine's branch (on
    // the bundled AC machine, A = -theta with C = 180 deg rather than A = +theta with C = 0, which
    // would run out of A's travel). Axes left out start at 0.
    std::map<char, double> start_axes;
    double spindle_rpm = 6000;                // M03, on from the log's start
    double idle_before_s = 0.5;               // standing at the path's start before it runs
    double idle_after_s = 0.5;                // standing at its end after it
    // The machine's interpolation period (its CNC period), acc/dec after interpolation, servo lag,
    // spindle acceleration and the posts' resolution. Acceleration before interpolation
    // (max_accel_mm_s2) is not used: the path's own timing is kept.
    motion_io::MachineModel machine;
    motion_io::ClientModel client;
    std::uint64_t seed = 1;
};

struct PathDryRun {
    std::size_t rows = 0;
    std::string program;      // the joint-space program the synth ran (machine-axis form, G93 pieces)
    std::string block;        // the sequence number of the path's pieces ("N30")
    // The command leaves the path's start at this log time (the CNC clock starts at the log's 0).
    double path_start_s = 0;
    // On a stretch where every axis moves at a steady rate, the actual axes trail the command by
    // this much: (n1 - 1) T / 2 + (n2 - 1) T / 2 for the two moving averages of n1, n2 periods T,
    // and T (1 - k) / k for the servo, k = 1 - exp(-T / servo time constant). So there the actual
    // pose at log time t is the path's at u = t - path_start_s - lag_s.
    double lag_s = 0;
};

// Writes the log (CSV, as motion_io::synthesize_nc_dry_run) of `machine` running spec.path with
// its tool tip. Deterministic for a given spec. Throws machine::KinematicsError when a pose is out
// of the machine's reach (naming the axis), std::invalid_argument for a bad spec.
PathDryRun synthesize_path_dry_run(const PathDryRunSpec& spec, const machine::Machine& machine, std::ostream& csv);

// Document 000, section 1.3 (eqs. 5.10/5.11 = 6.3/6.4; docs/five_axis.md, section 8), with
// theta = 2 pi t / 9 and t in [0, 1] s:
//   r_trj(t) = (0, 10 t cos theta + (20 - 20 t) sin theta, (20 t - 20) cos theta + 10 t sin theta)
//   r_pst(t) = (0, -sin theta, cos theta)
// put on the bundled AC table-table machine (data/machines/ac_table_table.json) with the path's
// origin at its rotary axes' intersection, home (-350, -275, -560); tool length 120 mm; spindle
// 6000 rpm; half a second standing before and after; the synth's machine (4 ms CNC period, acc/dec
// after interpolation, 5 ms servo lag, 0.001 mm and 0.001 deg posts) and client (about 6 ms cycles
// of 1.8, 2.0 and 2.25 ms reads with jitter).
PathDryRunSpec doc000_case_spec();
// The path's origin in workpiece coordinates, and the tool length.
inline constexpr std::array<double, 3> kDoc000OriginMm{-350, -275, -560};
inline constexpr double kDoc000ToolLengthMm = 120;

}  // namespace cutload::app
