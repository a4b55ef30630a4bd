// Use case: recommend feeds. A dry-run log, its run spec and NC program give, per cutting block,
// the feed that loads the tool to a target fraction of its limits, and the program rewritten with
// those feeds (only its F words change).
#pragma once

#include "app/control.hpp"
#include "app/inputs.hpp"
#include "app/program_run.hpp"
#include "app/program_source.hpp"
#include "force_model/feed_optimizer.hpp"
#include "force_model/force_model.hpp"
#include "motion_io/motion_io.hpp"

#include <cstddef>
#include <string>

namespace cutload::app {

struct OptimizeInput {
    std::string log_path;
    motion_io::ReadOptions read;
    force_model::RunSpec spec;                        // its limits are what the feeds aim at
    ProgramSource program;
    const force_model::Stock* base_stock = nullptr;
    force_model::Device device = force_model::Device::Cpu;
    // Target, feed range, basis and prediction budget; its `commanded` is taken from the program.
    force_model::FeedOptimizerOptions search;
};

struct OptimizeResult {
    motion_io::MotionModel motion;          // the log, named after the program's blocks
    ProgramRun program;                     // the program and its mapping onto the log
    force_model::FeedOptimization feeds;    // per block before / after, predictions before and after
    std::string program_text;               // the program with the recommended F words
    std::size_t changed_blocks = 0;         // blocks whose recommended feed differs from the programmed one
};

// Phases: Ingest, Program, Mapping, Optimize, Done. Throws what predict_run does, and
// force_model::SpecError when the spec sets none of the limits.
OptimizeResult optimize_feeds(const OptimizeInput& input, const Control& control = {});

}  // namespace cutload::app
