#include "stages/standard.hpp"

#include "stages/blocks.hpp"
#include "stages/hold.hpp"
#include "stages/resample.hpp"
#include "stages/sequence.hpp"
#include "stages/spindle.hpp"
#include "stages/stale.hpp"
#include "stages/survey.hpp"
#include "stages/unwrap.hpp"
#include "stages/velocity.hpp"

namespace cutload::motion_io::detail {

std::unique_ptr<StageChain> make_ingest_chain(Diagnostics& diag, GridSink& sink, const ChainSettings& s) {
    auto chain = std::make_unique<StageChain>(sink);
    chain->append(std::make_unique<Validate>(diag, s.physical));
    chain->append(std::make_unique<Sequence>(diag, s.limits));
    chain->append(std::make_unique<DropJumps>(diag, s.jumps));
    // After the glitches are gone: a dropped reading must not move the unwrap's reference.
    chain->append(std::make_unique<UnwrapRotary>(diag.facts()));
    // An event-driven log sends changes only: silences mean "held", and nothing is read twice.
    if (s.event_driven) chain->append(std::make_unique<HoldValues>());
    chain->append(std::make_unique<Survey>(diag, s.event_driven));
    if (!s.event_driven) chain->append(std::make_unique<StaleRepeats>(diag));
    chain->append(std::make_unique<ClockRecovery>(diag, s.event_driven, s.clock));
    chain->append(std::make_unique<Velocity>(s.slopes));
    chain->append(std::make_unique<Resample>(diag, s.step_s));
    chain->append(std::make_unique<SpindleAngle>(s.step_s));
    chain->append(std::make_unique<BlockAttribution>());
    chain->bind();
    return chain;
}

}  // namespace cutload::motion_io::detail
