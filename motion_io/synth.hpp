// Synthetic dry-run logs in the seed's sampling pattern (seed 001, section 4.2.3, table 4.1):
// an acceleration-limited machine updates its actual position on a CNC grid (4 ms), and an
// open-CNC client reads spindle speed, feed and position one after another (about 1.8, 2.0 and
// 2.25 ms each, with jitter), each with its own time stamp. Used for the bundled demo logs
// (data/demo_dryrun.csv, data/demo2_dryrun.csv), the tests and the benchmark.
//
// Two front ends share the machine and the client: a list of straight blocks (DryRunSpec, the
// first demo), and a parsed NC program (NcDryRunSpec: lines, arcs, helices, canned cycles,
// dwells and tool changes run the way a machine runs them, see data/README.md).
#pragma once

#include "motion_io/nc_program.hpp"

#include <cstddef>
#include <cstdint>
#include <ostream>
#include <string>
#include <vector>

namespace cutload::motion_io {

// One NC block, in machine coordinates.
struct ProgramBlock {
    std::string name;              // sequence number, e.g. "N10"
    bool rapid = false;            // G00 at the machine's rapid rate; otherwise G01 at feed_mm_min
    double target_mm[3] = {0, 0, 0};
    double feed_mm_min = 0;
};

// A FANUC-like machine: linear interpolation of the program at the CNC period, then
// acceleration/deceleration after interpolation (two cascaded moving averages, a bell-shaped
// velocity ramp that rounds corners inward and makes the feed dip there), then a first-order
// servo lag. The actual position is latched once per CNC period.
struct MachineModel {
    double cnc_period_s = 0.004;
    double rapid_mm_min = 30000;
    int accdec_ticks[2] = {8, 4};         // moving-average lengths (32 ms, 16 ms at 4 ms)
    double servo_time_constant_s = 0.005;
    double spindle_rpm = 10000;           // M03: positive
    double spindle_ramp_s = 0.5;          // 0 to spindle_rpm after start
    double spindle_ripple_rpm = 2;
    double position_resolution_mm = 0.001;
    double rotary_resolution_deg = 0.001;   // A/B/C readings (programs that turn rotary axes)
    // NC programs only (0: off, the first demo's machine). Acceleration/deceleration before
    // interpolation: the path speed changes at most this fast, rapids stop at their ends (in-
    // position check), a corner is taken no faster than the speed at which each axis's velocity
    // jumps by at most corner_speed_step_mm_min (FANUC's allowable speed difference), and an arc
    // no faster than sqrt(accel x radius).
    double max_accel_mm_s2 = 0;
    double corner_speed_step_mm_min = 600;
    double spindle_accel_rpm_s = 20000;   // NC programs: spindle speed changes (S, M03/M05, tool changes)
};

// The open-CNC client: sequential reads of spindle, feed, position per cycle.
struct ClientModel {
    double read_s[3] = {0.0018, 0.0020, 0.00225};   // spindle, feed, position
    double jitter_s = 0.00004;                      // standard deviation of each read's duration
    double start_s = 0.0013;                        // client's first read against the CNC clock
    // Now and then the logging PC stalls after a cycle (0: never, the first demo's client).
    double stall_probability = 0;
    double stall_s = 0.03;                          // mean stall; each is 0.5 to 1.5 times it
};

struct DryRunSpec {
    std::vector<ProgramBlock> program;
    double start_mm[3] = {0, 0, 0};   // machine position before the first block
    MachineModel machine;
    ClientModel client;
    double settle_s = 0.3;            // logging continues this long after the last block ends
    std::uint64_t seed = 1;
    std::size_t max_rows = 0;         // 0: until the program (and settle time) ends
};

// Writes the log as CSV with per-channel time stamps:
//   t_spindle [s], spindle [rpm], t_feed [s], feed [mm/min], t_pos [s], x [mm], y [mm], z [mm], block
// Deterministic for a given spec (own RNG). Returns the number of rows written.
std::size_t synthesize_dry_run(const DryRunSpec& spec, std::ostream& csv);

// How the machine changes tools: on a block that changes the tool the control stops the spindle,
// goes up to the change position's Z, across to its X/Y (rapids the program does not contain),
// changes (the logged tool number switches at the end) and carries on from there.
struct ToolChangeModel {
    double position_mm[3] = {450, 0, 0};   // machine coordinates
    double time_s = 4.0;
};

struct NcDryRunSpec {
    NcProgram program;                // parsed with the machine's work offsets (machine coordinates)
    double start_mm[3] = {0, 0, 0};   // machine position before the first block
    double start_deg[3] = {0, 0, 0};  // A, B, C before the first block
    MachineModel machine;
    ClientModel client;
    ToolChangeModel tool_change;
    double settle_s = 0.3;
    std::uint64_t seed = 1;
    std::size_t max_rows = 0;
};

// As synthesize_dry_run, with a tool column before the block column:
//   ..., z [mm], tool, block     (tool empty before the first change)
// A program that names rotary axes (machine-axis form, NcProgram::rotary_axes) gets their columns
// after z, in degrees at MachineModel::rotary_resolution_deg: ..., z [mm], a [deg], c [deg], tool,
// block. Every axis is interpolated in joint space and goes through the same acc/dec and servo
// lag as X/Y/Z; path speeds, accelerations and the feed reading count degrees as mm (FANUC).
std::size_t synthesize_nc_dry_run(const NcDryRunSpec& spec, std::ostream& csv);

// The demo program (geometry in docs: data/README.md): a pocket cleared by ramping, slotting and
// step-overs in two 3 mm levels, then the outer contour finished by a down cut at radial 1 mm,
// axial 3 mm, F6000, S10000 M03. Machine coordinates; work zero at machine (200, -300, -350).
DryRunSpec demo_dry_run_spec();

// The second demo (data/README.md): a multi-tool inch program as a 3-decimal post writes it, with
// absolute arc centres and neither G20 nor G90.1 (the control is set to both): face mill T1,
// a rotated pocket with an end mill T2 (helical entry, arcs), pecked holes with a drill T3.
std::string demo2_program_text();
// How to read it: inch, absolute arc centres, G54 at the stock's zero, start at the machine's
// tool-change position.
NcReadOptions demo2_read_options();
// demo2_program_text() run on the demo machine with acceleration-limited corners, tool changes
// and client stalls; its log is data/demo2_dryrun.csv.
NcDryRunSpec demo2_dry_run_spec();

// The third demo (data/README.md): a five-axis program in machine-axis form for the bundled AC
// table-table machine (data/machines/ac_table_table.json) that keeps the tool vertical: a ring
// groove cut by turning the C table under a standing tool, one turn in G93, one back in G94.
std::string demo3_program_text();
// How to read it: G54 at the C line on the stock top, rotary axes A and C, combined rotary feed,
// start above the groove.
NcReadOptions demo3_read_options();
// demo3_program_text() on demo2's machine and client; its log is data/demo3_dryrun.csv.
NcDryRunSpec demo3_dry_run_spec();

// The fourth demo (data/README.md): 3+2 work on the same AC machine. The table indexes to A-20 in
// the air, then a D10 ball-end mill finishes three passes along the part's X on the top face with
// its axis leaning 20 deg toward the part's +Y (the engine's fixed tilt, docs/five_axis.md 2.5).
std::string demo4_program_text();
// How to read it: G54 at the rotary axes' intersection, rotary axes A and C, start above the
// first pass.
NcReadOptions demo4_read_options();
// demo4_program_text() on demo2's machine and client; its log is data/demo4_dryrun.csv.
NcDryRunSpec demo4_dry_run_spec();

}  // namespace cutload::motion_io
