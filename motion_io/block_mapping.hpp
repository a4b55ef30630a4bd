// Attributes the samples of a motion log to NC program blocks when the log has no block channel
// (or to check the one it has): monotone matching of the actual path against the programmed
// path, then a time lead that models how far the CNC's block counter runs ahead of the actual
// position (acceleration/deceleration after interpolation and servo lag, typically 20-40 ms).
#pragma once

#include "motion_io/motion_io.hpp"
#include "motion_io/nc_program.hpp"

#include <atomic>
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace cutload::motion_io {

struct BlockMappingOptions {
    double max_distance_mm = 5;   // a sample farther from the program than this is unmatched (-1)
    double lead_s = 0;            // the block channel leads the geometric match by this much
    double slack_mm = 2;          // search window ahead of the last match, beyond 3x the sample's travel
    // Unmatched samples that do not count against the match (real dry runs spend long stretches
    // off the program's path): slower than rest_speed_mm_min (waiting, parked), or at rapid speed
    // (faster than the program's fastest cutting feed and than rapid_fraction x rapid_mm_min)
    // and farther than away_mm from every cutting move (rapids the control makes on its own).
    double rest_speed_mm_min = 30;
    double away_mm = 10;
    double rapid_mm_min = 30000;   // the machine's G00 rate
    double rapid_fraction = 0.4;
    // Set from any thread to stop: mapping a long log against a long program takes seconds, so
    // the flag is read every few thousand samples and MappingCancelled thrown.
    const std::atomic<bool>* cancel = nullptr;
};

// Mapping stopped by BlockMappingOptions::cancel (the application layer reports it as its cancel).
class MappingCancelled : public std::runtime_error {
public:
    MappingCancelled() : std::runtime_error("block mapping cancelled") {}
};

struct BlockMappingQuality {
    std::size_t samples = 0, matched = 0;
    double matched_fraction = 0;                    // matched / samples
    // Unmatched samples left out of the count, by reason (disjoint): a tool change (between the
    // moves around a block that changes the tool), at rest, a rapid away from the cutting moves.
    std::size_t excluded_tool_change = 0, excluded_at_rest = 0, excluded_away = 0;
    double excluded_fraction = 0;                   // all three / samples
    double counted_matched_fraction = 0;            // matched / (samples - excluded): the match that counts
    double mean_distance_mm = 0, p95_distance_mm = 0, max_distance_mm = 0;   // matched samples
    double coverage = 0;                            // fraction of the programmed path length reached
    std::vector<std::string> blocks_without_samples;   // moving blocks no sample matched
    std::optional<double> agreement;                // logs with a block channel: fraction of samples
                                                    // whose mapped block equals the logged one
};

struct BlockMapping {
    std::vector<std::int32_t> program_block;   // per sample: index into program.blocks (geometric), -1 unmatched
    std::vector<double> distance_mm;           // per sample: distance to the matched program point (NaN unmatched)
    std::vector<double> path_mm;               // per sample: arc length of the matched point
    std::vector<std::int32_t> block;           // per sample after the lead: index into block_names, -1 unmatched
    std::vector<std::string> block_names;      // program_block_names(program)
    BlockMappingQuality quality;
};

// Samples are matched geometrically, then shifted by the lead; a stretch of samples at rest or
// off the path between two moves of the program that has a block taking time without moving
// (a dwell, a tool change) in between is attributed to that block, as the CNC's counter names it.
BlockMapping map_blocks(const MotionModel& motion, const NcProgram& program, const BlockMappingOptions& opt);

// The motion with its block channel replaced by the mapping's.
MotionModel with_mapped_blocks(MotionModel motion, const BlockMapping& mapping);

// Fraction of samples, among those a carries a block for, where a and b name the same block.
double block_agreement(const MotionModel& a, const std::vector<std::int32_t>& b_block,
                       const std::vector<std::string>& b_names);

// The lead (0 .. max_lead_s, in steps of the motion's step) at which mapping a log that has a
// block channel agrees best with it: calibrate once per machine, then map logs without one.
double estimate_block_lead_s(const MotionModel& logged, const NcProgram& program, const BlockMappingOptions& opt,
                             double max_lead_s = 0.2);

}  // namespace cutload::motion_io
