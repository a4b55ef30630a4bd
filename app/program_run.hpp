// A dry run read together with the NC program it runs: the program interpreted in the log's
// machine coordinates, the log's samples attributed to program blocks (its own block channel, or
// block mapping when it has none), and the commanded-vs-actual prediction and comparison.
// The steps of app::predict_run and app::optimize_feeds (app/predict_run.hpp, app/optimize.hpp).
#pragma once

#include "app/control.hpp"
#include "force_model/force_model.hpp"
#include "force_model/program_compare.hpp"
#include "motion_io/block_mapping.hpp"
#include "motion_io/commanded.hpp"
#include "motion_io/nc_program.hpp"

#include <array>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace cutload::machine {
struct Machine;
}

namespace cutload::app {

using force_model::BlockComparison;
using force_model::Prediction;
using force_model::PredictOptions;
using force_model::RunSpec;

struct ProgramSettings {
    // Machine position of G54..G59's tool-tip zero, mm; G54 defaults to -setup offset of the spec.
    std::map<std::string, std::array<double, 3>> work_offsets_mm;
    std::vector<std::string> ignore_words;   // e.g. "G28", "H": dropped before interpretation
    double rapid_mm_min = 30000;             // the machine's G00 rate (commanded motion)
    double block_lead_ms = 0;                // block counter lead for logs without a block channel
    bool map_blocks = false;                 // map even when the log names the program's blocks
    bool decimal_less_is_increment = false;  // FANUC 3401#0 = 0: X10 means 10 least increments
    motion_io::ArcCenters arc_centers = motion_io::ArcCenters::Incremental;   // until G90.1 / G91.1
    motion_io::ProgramUnits program_units = motion_io::ProgramUnits::Mm;      // until G20 / G21
    double arc_tolerance_mm = motion_io::NcReadOptions{}.arc_tolerance_mm;   // plus 0.01 % of the radius
    bool tool_change_on_t = false;           // T alone changes the tool (no M06)
    bool block_skip = false;                 // the block skip switch is on: '/' blocks are skipped
    double min_match = 0.5;                  // of the counted samples near the path, or the program is refused
    motion_io::NcLimits limits;              // physical ranges, and the work a program may imply
    // Five-axis programs (machine-axis form): the machine's rotary axes ("AC"; set from the machine
    // definition, empty without one: A/B/C words are then an error) and how a G94 feed applies to a
    // G01 that turns one.
    std::string rotary_axes;
    motion_io::RotaryFeed rotary_feed = motion_io::RotaryFeed::Combined;
    std::array<double, 3> start_deg{};       // A, B, C before the first block (the log's first angles)
    // The machine's kinematics for tool-centre-point programs (G43.4/G43.5): app::
    // tool_centre_point_kinematics(machine, tool length). Null without a machine: those codes are
    // then an error naming the line and the word.
    std::shared_ptr<const motion_io::ToolCentrePointKinematics> tool_centre_point;
};

struct ProgramRun {
    motion_io::NcProgram program;
    motion_io::BlockMapping mapping;          // always computed: it gives the path deviations
    motion_io::CommandedOptions commanded;    // step of the log's model, the rapid rate
    bool mapped = false;                      // the motion's blocks come from the mapping
    bool tools_from_program = false;          // the motion's tools come from the program's blocks
    std::optional<double> estimated_lead_s;   // logs with their own block channel
};

// How to read the program against this spec and log: default work offsets from the spec's setup
// offset, overridden by settings; the machine starts at the log's first position (`start_mm`:
// log_start_mm(), or an inspect report's first_position_mm).
motion_io::NcReadOptions program_read_options(const ProgramSettings& settings, const RunSpec& spec,
                                              std::optional<std::array<double, 3>> start_mm);

// The log's first position (nullopt for an empty log).
std::optional<std::array<double, 3>> log_start_mm(const motion_io::MotionModel& motion);

// Maps the log onto the program and relabels `motion`'s blocks with the program's names when the
// log has none that match (or settings.map_blocks). A log that names no tool takes the tools of the
// program's blocks (program_tools_per_sample). Throws motion_io::NcProgramError when under
// settings.min_match of the counted samples lie near the program's path (wrong program or work
// offset; samples at rest, rapids away from the cutting moves and tool changes are not counted),
// or when the commanded motion at the log's step would pass settings.limits.max_samples.
// control.cancel stops the mapping within a few thousand samples (motion_io::MappingCancelled,
// which the use cases' cancellable() reports as force_model::Cancelled); progress is not used.
ProgramRun prepare_program_run(motion_io::NcProgram program, const ProgramSettings& settings,
                               motion_io::MotionModel& motion, const Control& control = {});

// The tool in the spindle at each sample by the program: the tool of the sample's block (blocks
// that share a name and a tool; where a name spans several tools, the block matched to the sample
// geometrically), carried over samples no block names (the tool stays in the spindle until a
// change; before the first named sample, the first tool named). -1 throughout when the program
// changes no tool.
std::vector<std::int32_t> program_tools_per_sample(const motion_io::NcProgram& program,
                                                   const motion_io::BlockMapping& mapping,
                                                   const motion_io::MotionModel& motion);

// Commanded time -> actual time, piecewise linear: each program block's commanded span is
// stretched onto the span the machine took for it (the mapping's first sample of each block), so
// a block lines up when the two predictions are plotted on one time axis. Before the first knot
// and after the last, a plain shift.
struct TimeWarp {
    std::vector<double> commanded_s, actual_s;   // knots, both strictly increasing
    double operator()(double t_commanded_s) const;
};

TimeWarp commanded_to_actual_time(const ProgramRun& run, const motion_io::MotionModel& actual);

struct ProgramPrediction {
    Prediction commanded;                  // from the programmed path at programmed feed
    std::vector<BlockComparison> blocks;   // compare_program() rows, program order
    TimeWarp to_actual_time;               // for plotting `commanded` beside the actual forces
};

// Predicts the commanded motion with the same spec and options as the actual one and compares
// the two block by block. `motion` is the (relabelled) log `actual` was predicted from, in stock
// axes like the program. With `grid_from_stock` (a fixed tilt, ToolFrame::grid_from_stock: `spec`
// and the options' stock are in the tool's frame) the commanded motion is turned into that frame
// for the engine and its forces back into stock axes, as the actual ones were.
//
// With `turning` (the log's tool turns where it can reach the stock, and `run.program` is
// turning_workpiece_program's tip path) the commanded motion is made from the program in the
// machine's axes and goes through turning_motion, as the log did, to force_model::predict_turning:
// the commanded poses come from the chain, not from the tip path's pieces. Both programs share
// their block names and times, so the comparison and the time warp read `run.program`.
struct TurningCommand {
    const motion_io::NcProgram* machine_axes = nullptr;   // the program as read (machine-axis form)
    const machine::Machine* machine = nullptr;
    double tool_length_mm = 0;
};
ProgramPrediction predict_program(const ProgramRun& run, const motion_io::MotionModel& motion, const Prediction& actual,
                                  const RunSpec& spec, const PredictOptions& options,
                                  const force_model::Rotation3* grid_from_stock = nullptr,
                                  const TurningCommand* turning = nullptr);

}  // namespace cutload::app
