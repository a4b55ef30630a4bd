// Internal: stage "survey" - what the log holds, before any repair.
#pragma once

#include "stages/stage.hpp"

#include <optional>

namespace cutload::motion_io::detail {

// An interval between position readings in which the rotary axes turn by less than this share of
// the x, y, z travel (an angle counted at kRotaryMmPerDeg) counts as one in which they stand.
inline constexpr double kRotaryStandingShare = 0.1;

// Accepts sessions, positions, feed, spindle and block readings; emits them all but the feed,
// which nothing downstream uses. Counts readings and their intervals per channel, the feed of
// plain differencing of consecutive positions, their path length and the feed channel's
// integral (the feed-unit check), warns of gaps in polled logs, and fails a session whose
// time never advances. Fills the session summary's readings, first line and time span.
//
// The feed-unit check compares the two only over the intervals between position readings in which
// the rotary axes stand (kRotaryStandingShare): while a rotary axis turns, a control's feed counts
// its degrees as mm (FANUC's combined feed), or gives the tool tip's speed against the part, or is
// an inverse time (G93) - none of them the x, y, z path's rate, and the log does not say which. A
// three-axis log has no rotary axes: every interval counts. The feed is held between its readings.
class Survey final : public Stage {
public:
    Survey(Diagnostics& diag, bool event_driven);
    Flows accepts() const override {
        return Flow::Sessions | Flow::Positions | Flow::Feed | Flow::Spindle | Flow::Blocks;
    }
    Flows emits() const override { return Flow::Sessions | Flow::Positions | Flow::Spindle | Flow::Blocks; }
    void begin_session() override;
    void record(const Record& r) override;
    void end_session(SessionSummary& s) override;
    void report(IngestReport& report) const override;

    std::size_t position_reads() const { return pos_stats_.samples; }
    // Feed channel integrated over time divided by the path length of the positions, both over the
    // intervals in which the rotary axes stand (0: too little data there). About 1 when the feed's
    // unit is right; 60 for mm/min read as mm/s.
    double feed_to_path_ratio() const;

private:
    struct ChannelStats {
        std::size_t samples = 0;
        IntervalHistogram intervals;
        bool have_last = false;
        double last_t = 0;
        void add(double t_s);
    };
    void on_position(const Record& r);
    void on_feed(const Record& r);
    void advance_feed(double t_s);
    void follow_interval(double dt_s, std::size_t line);

    Diagnostics& diag_;
    bool event_driven_;
    // ---- per session ----
    SessionSummary session_;
    std::optional<Record> last_pos_;
    // The feed held since its last reading (mm/min), integrated up to feed_t_ since the last
    // position reading: the records come in time order.
    std::optional<double> feed_now_;
    double feed_t_ = 0, feed_since_pos_mm_ = 0;
    double usual_dt_ = 0;   // slowly following position-reading interval, for gap warnings
    // ---- whole log ----
    ChannelStats pos_stats_, feed_stats_, spindle_stats_, block_stats_, tool_stats_;
    bool have_raw_feed_ = false;
    double raw_min_ = 0, raw_max_ = 0;
    double feed_integral_mm_ = 0, path_length_mm_ = 0;
};

}  // namespace cutload::motion_io::detail
