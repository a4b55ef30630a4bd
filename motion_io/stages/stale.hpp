// Internal: stage "stale_repeats" - a position read again before the CNC latched a new one.
#pragma once

#include "stages/stage.hpp"

#include <optional>

namespace cutload::motion_io::detail {

// Accepts and emits sessions and positions (polled logs only: an event-driven log sends changes
// only). A reading identical to the previous one while the machine moves (the previous pair or
// the next reading differs) is the same latched value read twice and carries no new sample:
// dropped and counted (`stale_repeat`). At standstill repeats are genuine and kept. Holds one
// reading, since the next one decides.
class StaleRepeats final : public Stage {
public:
    explicit StaleRepeats(Diagnostics& diag) : Stage("stale_repeats"), diag_(diag) {}
    Flows accepts() const override { return Flow::Sessions | Flow::Positions; }
    Flows emits() const override { return Flow::Sessions | Flow::Positions; }
    void begin_session() override;
    void record(const Record& r) override;
    void end_session(SessionSummary& s) override;
    void report(IngestReport& report) const override;
    std::size_t dropped() const { return dropped_; }

private:
    void settle_held(bool next_differs);

    Diagnostics& diag_;
    std::optional<Record> prev2_, prev1_, held_;
    std::size_t dropped_ = 0;
};

}  // namespace cutload::motion_io::detail
