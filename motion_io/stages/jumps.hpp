// Internal: stage "drop_jumps" - position readings that jump where no machine can go.
#pragma once

#include "stages/stage.hpp"

#include <optional>
#include <vector>

namespace cutload::motion_io::detail {

struct JumpLimits {
    double max_speed_mm_min = 200000;   // no machine tool traverses faster (200 m/min)
    double slack_s = 0.002;             // time-stamp jitter; a reading may show a tick newer than its stamp
    double slack_mm = 0.01;             // position quantisation
    std::size_t max_glitch_readings = 32;   // an excursion longer than this that never comes back is real
};

// Accepts and emits sessions and positions. A reading is reachable from another when the
// distance between them can be covered at max_speed_mm_min in the time between them (plus the
// slack). A reading not reachable from the last accepted one (the anchor) starts an excursion;
// the excursion ends
//  - as a glitch (dropped, `glitch_dropped`) when a reading is reachable from the anchor but not
//    from the excursion's last reading: the log jumped away and back;
//  - as a real jump (kept, `position_jump`) when a reading is reachable from both (the log goes on
//    from where it jumped to), or when the excursion grows to max_glitch_readings readings
//    without coming back;
//  - at the end of a session, as a glitch (it never came back).
// At the start of a session the first readings are held until two consecutive ones are
// reachable from each other: earlier ones not reachable from that pair are glitches.
// Other channels are untouched (ranges are the validate stage's).
class DropJumps final : public Stage {
public:
    DropJumps(Diagnostics& diag, JumpLimits limits = {});
    Flows accepts() const override { return Flow::Sessions | Flow::Positions; }
    Flows emits() const override { return Flow::Sessions | Flow::Positions; }
    void begin_session() override;
    void record(const Record& r) override;
    void end_session(SessionSummary& s) override;
    std::size_t dropped() const { return dropped_; }

private:
    bool reachable(const Record& from, const Record& to) const;
    void start_up(const Record& r);
    void settle_start(std::size_t pair_end);
    void follow(const Record& r);
    void accept(const Record& r);
    void accept_excursion();
    void drop(const std::vector<Record>& readings, const Record& from, const char* why);

    Diagnostics& diag_;
    JumpLimits limits_;
    double max_speed_mm_s_;
    std::optional<Record> anchor_;
    std::vector<Record> held_;   // start-up readings, or the current excursion
    std::size_t dropped_ = 0;
};

}  // namespace cutload::motion_io::detail
