// Internal: stage "survey" - what the log holds, before any repair.
#pragma once

#include "stages/stage.hpp"

#include <optional>
#include <utility>

namespace cutload::motion_io::detail {

// Accepts sessions, positions, feed, spindle and block readings; emits them all but the feed,
// which nothing downstream uses. Counts readings and their intervals per channel, the feed of
// plain differencing of consecutive positions, their path length and the feed channel's
// integral (the feed-unit check), warns of gaps in polled logs, and fails a session whose
// time never advances. Fills the session summary's readings, first line and time span.
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
    // Feed channel integrated over time divided by the path length of the positions (0: too
    // little data). About 1 when the feed's unit is right; 60 for mm/min read as mm/s.
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
    void follow_interval(double dt_s, std::size_t line);

    Diagnostics& diag_;
    bool event_driven_;
    // ---- per session ----
    SessionSummary session_;
    std::optional<Record> last_pos_;
    std::optional<std::pair<double, double>> last_feed_;   // (t_s, mm/min) for the feed integral
    double usual_dt_ = 0;   // slowly following position-reading interval, for gap warnings
    // ---- whole log ----
    ChannelStats pos_stats_, feed_stats_, spindle_stats_, block_stats_, tool_stats_;
    bool have_raw_feed_ = false;
    double raw_min_ = 0, raw_max_ = 0;
    double feed_integral_mm_ = 0, path_length_mm_ = 0;
};

}  // namespace cutload::motion_io::detail
