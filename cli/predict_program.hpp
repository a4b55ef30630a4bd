// NC program support shared by `cutload predict --program` and `cutload optimize`: reading the
// program against the run spec and the log, giving the log the program's block names (its own
// block channel, or block mapping), and the commanded-vs-actual comparison.
#pragma once

#include "force_model/force_model.hpp"
#include "force_model/program_run.hpp"

#include <CLI/CLI.hpp>

#include <optional>
#include <string>
#include <vector>

namespace cutload::cli {

struct ProgramOptions {
    std::string program;                      // empty: no program (predict without --program)
    std::vector<std::string> work_offsets;    // "G55=x,y,z" (mm, machine position of the tool-tip zero)
    std::vector<std::string> ignore;          // words to drop, e.g. G28, H
    double rapid_mm_min = 30000;
    double block_lead_ms = 0;
    bool map_blocks = false;                  // attribute blocks by mapping even if the log has them
    bool decimal_less_increment = false;
    std::string arc_centers = "incremental";  // until G90.1 / G91.1
    std::string program_units = "mm";         // until G20 / G21
    double arc_tolerance_mm = motion_io::NcReadOptions{}.arc_tolerance_mm;
    bool tool_change_on_t = false;
    bool block_skip = false;
    double min_match = 0.5;
    motion_io::NcLimits limits;               // --max-program-* options set the work bounds
    std::string compare_csv, commanded_out;   // predict only
    bool commanded_from_log = false;          // predict only: the log's own commanded positions
};

// --program and its companions; `for_predict` adds --compare, --commanded-out and --commanded-from-log.
void add_program_options(CLI::App& cmd, ProgramOptions& o, bool for_predict);

// force_model's ProgramRun, absent when no --program was given.
struct ProgramRun {
    bool active = false;
    force_model::ProgramRun run;
};

// Without --program: inactive, motion untouched. With it: reads the program (G54 = -setup offset
// unless --work-offset says otherwise; start = the log's first position) and relabels `motion`'s
// blocks with the program's names when the log has none that match (or --map-blocks).
ProgramRun prepare_program_run(const ProgramOptions& o, motion_io::MotionModel& motion, const force_model::RunSpec& spec);

// Prints the block mapping's quality (and the calibrated lead when the log had blocks).
void print_mapping(const ProgramRun& run);

// Predicts the commanded motion, writes --commanded-out, --compare and BLOCKS.csv (`blocks_csv`,
// unless empty) with the comparison columns, prints the cutting blocks' comparison. No-op when
// inactive.
void finish_program_run(const ProgramOptions& o, const ProgramRun& run, const motion_io::MotionModel& motion,
                        const force_model::Prediction& actual, const force_model::RunSpec& spec,
                        const force_model::PredictOptions& opt, const std::string& blocks_csv);

// With --commanded-from-log: reads the log again with its commanded positions (`read` is how the
// actual motion was read), predicts that motion, writes --commanded-out, --compare and BLOCKS.csv
// with the comparison columns and prints the comparison. No-op without the flag.
void finish_logged_commanded(const ProgramOptions& o, const std::string& log, const motion_io::ReadOptions& read,
                             const motion_io::MotionModel& motion, const force_model::Prediction& actual,
                             const force_model::RunSpec& spec, const force_model::PredictOptions& opt,
                             const std::string& blocks_csv);

// The device choice of `--device opencl|cpu|auto` (auto: OpenCL when a device exists).
force_model::Device choose_device(const std::string& name);

}  // namespace cutload::cli
