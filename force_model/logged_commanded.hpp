// The commanded path a controller logged beside the actual one (X1_CommandPosition beside
// X1_ActualPosition; docs/formats.md, "Commanded positions"): the interpolator's output, before
// servo lag and corner rounding. Read as a motion of its own (motion_io::Positions::Commanded) and
// predicted with the same spec, it is the commanded prediction of seed 001 (figs. 4.16-4.17)
// without an NC program; this compares it with the actual one block by block, in the rows of
// compare_program(), so write_comparison_csv() and comparison_block_columns() carry it.
#pragma once

#include "force_model/force_model.hpp"
#include "force_model/program_compare.hpp"

#include <vector>

namespace cutload::force_model {

// `actual` and `commanded` are the same log read with actual and with commanded positions (same
// block channel, same sessions). Rows in the order blocks first occur in `actual`. The commanded
// feed of a block (its mean in `commanded`) stands where compare_program() has the programmed
// feed; deviations are the distance between the actual and the commanded position at the same
// time; `rapid` is false (a log does not say which moves are G00).
std::vector<BlockComparison> compare_logged_commanded(const motion_io::MotionModel& actual,
                                                      const motion_io::MotionModel& commanded,
                                                      const Prediction& commanded_prediction,
                                                      const Prediction& actual_prediction);

}  // namespace cutload::force_model
