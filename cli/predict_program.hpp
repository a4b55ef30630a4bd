// NC program options shared by `cutload predict --program` and `cutload optimize`, and how their
// results are shown: the program's mapping onto the log and the commanded-vs-actual comparison.
// Reading the program, mapping and predicting are the app layer's (app/predict_run.hpp).
#pragma once

#include "app/predict_run.hpp"

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
    std::string rotary_feed = "combined";     // how G94 F applies to a G01 that turns a rotary axis (with --machine)
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

// The program to read with the log (nullopt without --program; then --compare and
// --commanded-out are usage errors). G54 = -setup offset unless --work-offset says otherwise.
std::optional<app::ProgramSource> program_source(const ProgramOptions& o);

// Prints the block mapping's quality (and the calibrated lead when the log had blocks).
void print_mapping(const app::ProgramRun& run);

// With a commanded path (a program or --commanded-from-log): writes --commanded-out, --compare
// and BLOCKS.csv (`blocks_csv`, unless empty) with the comparison columns, prints the mapping and
// the cutting blocks' comparison. No-op without one.
void finish_program_run(const ProgramOptions& o, const app::RunResult& r, const std::string& blocks_csv);

}  // namespace cutload::cli
