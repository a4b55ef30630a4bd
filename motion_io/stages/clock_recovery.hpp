// Internal: stage "clock" - recovers the CNC's update grid and puts each reading at its tick.
#pragma once

#include "stages/clock.hpp"
#include "stages/stage.hpp"

#include <optional>
#include <vector>

namespace cutload::motion_io::detail {

struct ClockLimits {
    // Readings timed together. Each batch's phase chunks (64 readings) start at its first
    // reading; a smaller batch lowers the latency of a live source at the price of other chunk
    // boundaries (ticks then differ from the file's by microseconds). The period is estimated
    // from the first 1024 readings at any batch size. Event-driven sources have no grid: each
    // reading is passed on as soon as its successor arrives, whatever the batch size.
    std::size_t batch_readings = 1024;
    // Threads the period scan may use (estimate_update_period): 1 where another thread of the
    // process needs the second core.
    unsigned scan_threads = 2;
};

// Accepts sessions and positions; emits sessions and ticks. Polled logs: the update period is
// estimated from the first moving stretch of a session (estimate_update_period, waiting for 40
// moving pairs within 16384 readings, retried up to 3 times; a session that ends sooner is
// calibrated at its end from as few as 12), the tick phase per chunk of 64 readings
// (best_phase), each reading is put at the tick it shows on a reference grid that follows the
// chunk phases slowly, and two readings on one tick are moved apart. Event-driven logs, or no
// period found: each reading keeps its time stamp. Fills the session summary's period. At most 8
// scans for the period per log: a short session, or any session once they are spent, takes the
// period an earlier session found when it fits (period_fits), so a log of many short sessions
// costs no more per reading than one long session; a session left without one is warned
// (`period_not_estimated`).
class ClockRecovery final : public Stage {
public:
    ClockRecovery(Diagnostics& diag, bool event_driven, ClockLimits limits = {});
    Flows accepts() const override { return Flow::Sessions | Flow::Positions; }
    Flows emits() const override { return Flow::Sessions | Flow::Ticks; }
    void begin_session() override;
    void record(const Record& r) override;
    void end_session(SessionSummary& s) override;
    double period_s() const { return period_s_; }

private:
    void process_batch(bool final);
    bool calibrate(bool final);
    void time_chunk(std::size_t begin, std::size_t end);
    void warn_short_stretch(const UpdatePeriod& found, std::size_t reads);
    double tick_of(std::size_t pending_index) const;
    double wrap_half_period(double d) const;
    void follow_phase();
    // t_s since the origin; stamp_s: the reading's own stamp, emitted as it is (no grid).
    void add_tick(double t_s, std::optional<double> stamp_s, const PosRead& r);

    Diagnostics& diag_;
    bool event_driven_;
    ClockLimits limits_;
    std::vector<PosRead> pending_;          // times since origin_s_
    std::vector<double> pending_stamp_s_;   // their stamps as read
    double period_s_ = 0, phase_s_ = 0, ref_phase_s_ = 0;
    bool have_ref_phase_ = false;
    int calibration_attempts_ = 0;
    // Across the sessions of one log: the period found last and the scans made (bounded work).
    double known_period_s_ = 0;
    std::size_t scans_ = 0;
    std::optional<PosRead> last_committed_;
    std::optional<Tick> last_tick_;         // time since origin_s_
    double last_tick_stamp_s_ = 0;          // last_tick_'s time as emitted
    std::size_t first_line_ = 0;
    bool have_first_line_ = false;
    // The session's first time stamp. The clock works on times since it, so that its trial grids
    // (phases k * period / n) are anchored at the session, not at the log's time zero: a log
    // shifted by a constant then gives the same ticks, shifted by it, and a machine clock that has
    // run for days keeps the precision of a small number.
    double origin_s_ = 0;
};

}  // namespace cutload::motion_io::detail
