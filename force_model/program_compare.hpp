// Per-block comparison of the machine's actual motion with the NC program's commanded motion,
// and of the forces predicted from each (seed 001, figs. 4.16-4.17: the program's prediction is
// wrong where the machine departs from the program, i.e. at corners).
#pragma once

#include "force_model/force_model.hpp"
#include "motion_io/block_mapping.hpp"
#include "motion_io/commanded.hpp"
#include "motion_io/nc_program.hpp"

#include <string>
#include <vector>

namespace cutload::force_model {

struct BlockComparison {
    std::string block;
    bool rapid = false;
    double programmed_feed_mm_min = 0;   // rapids: the rapid rate
    std::size_t samples = 0;             // actual motion samples attributed to the block
    // Distance of the actual path from the programmed one (monotone match, whole program).
    double max_deviation_mm = 0, mean_deviation_mm = 0;
    double actual_min_feed_mm_min = 0, actual_mean_feed_mm_min = 0, actual_max_feed_mm_min = 0;
    double feed_deficit_pct = 0;         // how far the actual feed drops below the programmed one
    double feed_surge_pct = 0;           // how far it rises above it
    double commanded_duration_s = 0, actual_duration_s = 0;
    double commanded_peak_force_N = 0, actual_peak_force_N = 0;
    double force_difference_N = 0;       // actual - commanded
    double force_difference_pct = 0;     // of the commanded peak; 0 when that is 0
};

// `actual` carries program block names (a log's own block channel or a mapping's); `mapping` is
// map_blocks(actual, program) and supplies the deviations. One row per block name that takes time
// in either motion, in program order.
std::vector<BlockComparison> compare_program(const motion_io::NcProgram& program, const motion_io::MotionModel& actual,
                                             const motion_io::BlockMapping& mapping, const Prediction& commanded_prediction,
                                             const Prediction& actual_prediction, const motion_io::CommandedOptions& commanded);

// The CSV columns of write_comparison_csv, in order (also the service's comparison CSV).
const std::vector<std::string>& comparison_columns();

void write_comparison_csv(const std::vector<BlockComparison>& rows, const std::string& path);

// The comparison as extra BLOCKS.csv columns, matched by block name (empty for a block the
// comparison lacks): commanded_peak_force_N, force_difference_N, force_difference_pct,
// max_deviation_mm, mean_deviation_mm, feed_deficit_pct, feed_surge_pct.
BlockCsvExtra comparison_block_columns(const std::vector<BlockComparison>& rows);

}  // namespace cutload::force_model
