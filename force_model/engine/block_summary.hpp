// Internal: per-block summaries and overload flags from the engine's rows.
#pragma once

#include "engine/rows.hpp"
#include "force_model/force_model.hpp"

#include <cstdint>
#include <string>
#include <vector>

namespace cutload::force_model {

// One block's summary built up row by row: the only place its figures and flags are worked out,
// whether a whole run's rows are summarised at once (predict) or a live run's arrive in batches
// (streaming), so a block split across batches ends with the same summary as in one piece.
class BlockAccumulator {
public:
    BlockAccumulator(std::string name, double t_s);
    // A motion sample of the block: its time span is that of its samples.
    void add_motion(double t_s);
    // `limits`: by the row's cutter slot (RowExtra::slot); slot -1 flags unknown_tool.
    void add_row(const ForceSample& s, const RowExtra& x, const std::vector<Limits>& limits);
    // The summary so far: mean over the cutting rows, the tool that cut most of its rows.
    BlockSummary summary() const;
    double t_end_s() const { return b_.t_end_s; }

private:
    struct ToolCount {
        std::int32_t tool;
        std::size_t rows;
    };
    BlockSummary b_;
    double force_sum_N_ = 0;
    std::size_t cutting_rows_ = 0;
    std::vector<ToolCount> tools_;   // cutting rows per T number (a block rarely sees more than one)
};

// Every block's summary over a whole motion model, its rows added as they come (in any number of
// pieces): one summary per block in order of first appearance in the motion, then blocks that only
// rows name; rows without a block (a negative index) are summarised as "(none)".
class BlockSummaries {
public:
    // `limits`: by the rows' cutter slot (RowExtra::slot; the tool's own limits over the run's).
    // Rows of an unknown tool (slot -1) flag unknown_tool.
    // With a window (PredictOptions::window): the blocks it covers, their spans clipped to it.
    BlockSummaries(const motion_io::MotionModel& motion, std::vector<Limits> limits,
                   const TimeWindow* window = nullptr);
    void add_rows(const ForceSample* rows, const RowExtra* extra, std::size_t n);
    std::vector<BlockSummary> result() const;

private:
    BlockAccumulator& at(std::int32_t block, double t_s);
    const std::vector<std::string>& block_names_;
    std::vector<Limits> limits_;
    std::vector<BlockAccumulator> acc_;
    std::vector<std::ptrdiff_t> index_;   // by block index + 1: position in acc_, -1 none yet
};

// BlockSummaries over all the rows at once.
std::vector<BlockSummary> summarise_blocks(const motion_io::MotionModel& motion, const std::vector<ForceSample>& rows,
                                           const std::vector<RowExtra>& extra, const std::vector<Limits>& limits);

// The name a block index is summarised under ("(none)" for rows without a block).
std::string block_name(const std::vector<std::string>& block_names, std::int32_t block);

// The rows of a Prediction are checked as they leave the engine (check_finite_rows); this checks
// its block summaries and flags (std::runtime_error naming the block).
void check_finite_summaries(const Prediction& p);

}  // namespace cutload::force_model
