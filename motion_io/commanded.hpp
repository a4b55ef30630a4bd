// The commanded motion: the programmed path at the programmed feed, with no acceleration, no
// servo lag and an instant spindle, sampled like a repaired log (uniform step, C1 interpolant per
// interval, blocks named as the log names them). This is what CAM-side force checks assume the
// machine does; run through the same force engine it gives the "conventional" prediction of seed
// 001, figs. 4.16-4.17.
#pragma once

#include "motion_io/motion_io.hpp"
#include "motion_io/nc_program.hpp"

#include <vector>

namespace cutload::motion_io {

struct CommandedOptions {
    double step_s = 0.001;
    double rapid_mm_min = 30000;             // G00 path speed (machine data)
    std::vector<double> feed_mm_min;         // per program block; empty or <= 0: the programmed feed
    double max_samples = NcLimits{}.max_samples;   // refuse (NcProgramError) rather than build more
};

// Seconds each program block takes at its commanded speed (dwell: its time; modal-only: 0).
std::vector<double> commanded_durations_s(const NcProgram& program, const CommandedOptions& opt);

// The number of samples commanded_motion() would build, from the durations alone.
double commanded_sample_count(const NcProgram& program, const CommandedOptions& opt);

// Throws std::invalid_argument when the program has no motion, NcProgramError when it would take
// more than opt.max_samples samples. The per-sample tool is the block's tool (-1 before the first
// change).
MotionModel commanded_motion(const NcProgram& program, const CommandedOptions& opt);

// The MotionModel block names of a program: one per distinct block name, in program order
// (blocks that share an N number share a name, as in a log).
std::vector<std::string> program_block_names(const NcProgram& program);

}  // namespace cutload::motion_io
