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
    std::string compare_csv, commanded_out;   // predict only
};

// --program and its companions; `for_predict` adds --compare and --commanded-out.
void add_program_options(CLI::App& cmd, ProgramOptions& o, bool for_predict);

// The program to read with the log (nullopt without --program; then --compare and
// --commanded-out are usage errors). G54 = -setup offset unless --work-offset says otherwise.
std::optional<app::ProgramSource> program_source(const ProgramOptions& o);

// Prints the block mapping's quality (and the calibrated lead when the log had blocks).
void print_mapping(const app::ProgramRun& run);

// With a program: writes --commanded-out, --compare and BLOCKS.csv (`blocks_csv`, unless empty)
// with the comparison columns, prints the mapping and the cutting blocks' comparison. No-op
// without one.
void finish_program_run(const ProgramOptions& o, const app::RunResult& r, const std::string& blocks_csv);

}  // namespace cutload::cli
