// Internal: stage "hold" - for event-driven logs, makes "value held" explicit.
#pragma once

#include "stages/stage.hpp"

#include <array>

namespace cutload::motion_io::detail {

// Accepts and emits sessions, positions and spindle readings. An event-driven source (SHDR,
// MTConnect) sends a value only when it changes, so silence means "unchanged". The next value
// after a silence longer than twice the usual update interval (the median of the last 15)
// started to change at most one interval earlier: a copy of the held value there keeps the
// resampling from smearing the move over the whole silence. A silence left by a reading dropped as
// a glitch (Record::after_glitch) is no hold: the value went on changing.
class HoldValues final : public Stage {
public:
    HoldValues() : Stage("hold") {}
    Flows accepts() const override { return Flow::Sessions | Flow::Positions | Flow::Spindle; }
    Flows emits() const override { return Flow::Sessions | Flow::Positions | Flow::Spindle; }
    void begin_session() override;
    void record(const Record& r) override;

private:
    static constexpr std::size_t kIntervalRing = 15;
    struct Held {
        bool have = false;
        Record last;
        std::array<double, kIntervalRing> intervals{};
        std::size_t n_intervals = 0;
    };
    Held pos_, spindle_;
};

}  // namespace cutload::motion_io::detail
