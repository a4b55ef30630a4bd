// Internal: the chain of stages a log goes through (docs/ingest.md).
#pragma once

#include "stages/chain.hpp"
#include "stages/clock_recovery.hpp"
#include "stages/jumps.hpp"
#include "stages/validate.hpp"
#include "stages/velocity.hpp"

#include <memory>

namespace cutload::motion_io::detail {

struct ChainSettings {
    double step_s = 0.001;
    bool event_driven = false;   // values sent on change (SHDR) rather than polled
    StageLimits limits;          // sequence: reorder horizon, session gap
    PhysicalLimits physical;     // validate
    JumpLimits jumps;            // drop_jumps
    ClockLimits clock;           // clock
    SlopeLimit slopes;           // velocity
};

// Polled logs:       validate, sequence, drop_jumps, survey, stale_repeats, clock, velocity,
//                    resample, spindle_angle, blocks
// Event-driven logs: validate, sequence, drop_jumps, hold, survey, clock, velocity, resample,
//                    spindle_angle, blocks
// Bound, ready for records. The grid goes to `sink`.
std::unique_ptr<StageChain> make_ingest_chain(Diagnostics& diag, GridSink& sink, const ChainSettings& settings);

}  // namespace cutload::motion_io::detail
