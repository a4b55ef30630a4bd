// Feed recommendations (the seed's stated next step: lower the feed where the load is too high,
// raise it where it is needlessly low). Per block, the feed that brings the binding quantity
// (peak force, torque, power, chip thickness or bending stress: whichever is closest to its
// limit) to a target fraction of its limit, within the machine's feed range; predicted again
// with the new feeds to show the result.
#pragma once

#include "force_model/force_model.hpp"
#include "motion_io/commanded.hpp"
#include "motion_io/nc_program.hpp"

#include <string>
#include <vector>

namespace cutload::force_model {

// Which motion the forces are predicted from. Actual: the logged motion retimed block by block
// to the new feeds (the path as the machine actually moved it; the acceleration-limited corner
// rounding is kept as logged). Commanded: the program's own path at the new feeds.
enum class FeedBasis { Actual, Commanded };

struct FeedOptimizerOptions {
    double target = 0.8;              // fraction of each limit the binding quantity is brought to
    double min_feed_mm_min = 10;
    double max_feed_mm_min = 0;       // 0: 90 % of limits.rapid_feed_mm_min (faster reads as a rapid)
    double tolerance = 0.05;          // a block landing in target x (1 - tolerance) .. target is done
    int max_predictions = 8;          // of the search; up to 3 more lower blocks left over the target
    FeedBasis basis = FeedBasis::Actual;
    motion_io::CommandedOptions commanded;   // step and rapid rate (feeds are set by the optimizer)
    // Only blocks the engine flags at their programmed feed are changed; the others keep it.
    bool only_flagged = false;
    // Feeds are only ever lowered: a block under the target keeps its programmed feed.
    bool never_raise = false;
    // A changed feed is rounded down to a multiple of this (not below min_feed_mm_min rounded up
    // to it), so the program states feeds a shop would write; 0: only to what an F word can state.
    double feed_step_mm_min = 0;
};

struct BlockFeed {
    std::string block;
    double programmed_feed_mm_min = 0, recommended_feed_mm_min = 0;
    std::string binding;                       // force, torque, power, chip, bending
    double ratio_before = 0, ratio_after = 0;  // binding quantity / its limit
    bool at_feed_limit = false;                // the feed range stopped it short of the target
    std::vector<std::string> flags_before, flags_after;   // the block's engine flags (sorted, unique)
};

struct FeedOptimization {
    std::vector<BlockFeed> blocks;     // feed blocks that cut, in program order
    std::vector<double> feed_mm_min;   // per program block (0: not a feed move), for rewrite_feeds
    Prediction before, after;
    int predictions = 0;
    bool target_met = false;           // every block at most at target (within tolerance of it or at a feed limit)
    double max_ratio_after = 0;        // largest quantity / limit after, over all blocks and limits
    std::string max_ratio_block;       // where it is; over 1 means a limit is still exceeded (also
                                       // in blocks whose F the optimizer does not set, e.g. rapids)
};

// `actual` must carry the program's block names (its own block channel or map_blocks()); it is
// not used with FeedBasis::Commanded. Throws SpecError when the spec sets none of the limits.
FeedOptimization optimize_feeds(const motion_io::NcProgram& program, const motion_io::MotionModel& actual,
                                const RunSpec& spec, const PredictOptions& predict_options,
                                const FeedOptimizerOptions& options);

// The same path driven faster or slower, resampled onto the same uniform step. A sample of block b
// moving at or below programmed_mm_min[b] is sped up by speed_scale[b]. A faster one is carrying
// speed over from a neighbouring block (the tail of a rapid still decelerating, seed 001 section
// 2.4), and only the share programmed/actual of it follows block b's new feed:
// v' = v + (k - 1) F (F / v). Blocks -1, or with programmed 0: speed_scale alone.
motion_io::MotionModel retime_motion(const motion_io::MotionModel& motion, const std::vector<double>& speed_scale,
                                     const std::vector<double>& programmed_mm_min);

}  // namespace cutload::force_model
