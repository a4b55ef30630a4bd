// Internal: the repair stages of one log (per session): drop stale repeats, recover the CNC
// clock, time each reading at its tick, estimate velocity, resample onto the uniform grid with a
// cubic Hermite (C1) interpolant, integrate the spindle angle and attribute blocks.
#pragma once

#include "clock.hpp"
#include "pipeline.hpp"

#include <deque>
#include <array>
#include <optional>

namespace cutload::motion_io::detail {

class Repairer final : public SessionConsumer {
public:
    Repairer(Diagnostics& diag, GridSink& out, double step_s, bool event_driven);
    void begin_session() override;
    void record(const Record& r) override;
    void end_session() override;
    // Statistics of everything seen so far (counts, intervals, feed ranges, warnings).
    void fill_report(IngestReport& report) const;
    std::size_t position_reads() const { return pos_reads_total_; }
    // Feed channel integrated over time divided by the path length of the positions (0: too
    // little data). About 1 when the feed's unit is right; 60 for mm/min read as mm/s.
    double feed_to_path_ratio() const;

private:
    struct Knot {
        double t_s = 0;
        double p[3] = {0, 0, 0};
        double v[3] = {0, 0, 0};
    };
    struct ChannelStats {
        std::size_t samples = 0;
        IntervalHistogram intervals;
        bool have_last = false;
        double last_t = 0;
        void add(double t_s);
    };

    void on_pos(const Record& r);
    void stale_filter(const PosRead& read, std::size_t line);
    void accept_read(const PosRead& read);
    void process_batch(bool final);
    void warn_short_stretch(const UpdatePeriod& found, std::size_t reads);
    double tick_of(std::size_t pending_index) const;
    double wrap_half_period(double d) const;
    void follow_phase();
    void add_knot(double t_s, const double p[3]);
    void finalise_velocities(bool final);
    void push_hermite_knot(const Knot& k, bool last = false);
    void emit_until(const Knot& a, const Knot& b, bool include_end);
    double spindle_rpm_at(double t_s);
    std::int32_t block_at(double t_s);
    std::int32_t tool_at(double t_s);

    Diagnostics& diag_;
    GridSink& out_;
    double step_s_;
    bool event_driven_;

    // ---- per session ----
    std::optional<PosRead> prev2_, prev1_, held_;
    std::size_t held_line_ = 0;
    std::vector<PosRead> pending_;
    double period_s_ = 0, phase_s_ = 0, ref_phase_s_ = 0;
    bool have_ref_phase_ = false;
    int calibration_attempts_ = 0;
    std::optional<PosRead> last_committed_;
    std::deque<Knot> knots_;           // the velocity window around knots_[next_knot_]
    std::size_t next_knot_ = 0;        // first knot without a velocity
    std::optional<Knot> prev_hermite_;
    bool have_grid_ = false;
    double grid_t0_ = 0;
    std::size_t grid_i_ = 0;
    bool have_prev_sample_ = false;
    double prev_rpm_ = 0, angle_deg_ = 0;
    std::deque<std::pair<double, double>> spindle_;   // (t_s, rpm)
    std::deque<std::pair<double, std::int32_t>> blocks_;
    std::int32_t current_block_ = -1;
    std::deque<std::pair<double, std::int32_t>> tools_;
    std::int32_t current_tool_ = -1;
    std::size_t session_pos_reads_ = 0;
    double session_first_t_ = 0, session_last_t_ = 0;
    std::size_t session_first_line_ = 0;
    std::optional<PosRead> last_raw_;   // for plain differencing and path length
    std::optional<std::pair<double, double>> last_feed_;   // (t_s, mm/min) for the feed integral
    double usual_dt_ = 0;   // slowly following position-reading interval, for gap warnings

    // ---- whole log ----
    ChannelStats pos_stats_, feed_stats_, spindle_stats_, block_stats_, tool_stats_;
    std::size_t stale_dropped_ = 0;
    std::size_t pos_reads_total_ = 0;
    std::size_t sessions_ = 0;
    double duration_s_ = 0;
    double best_period_s_ = 0;
    std::size_t best_period_reads_ = 0;
    bool have_raw_feed_ = false, have_rep_feed_ = false;
    double raw_min_ = 0, raw_max_ = 0, rep_min_ = 0, rep_max_ = 0;
    std::array<double, 3> first_position_mm_{};
    double feed_integral_mm_ = 0, path_length_mm_ = 0;
};

}  // namespace cutload::motion_io::detail
