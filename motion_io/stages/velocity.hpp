// Internal: stage "velocity" - the velocity of the motion at each tick.
#pragma once

#include "stages/stage.hpp"

#include <deque>
#include <optional>

namespace cutload::motion_io::detail {

// The slope limit at a knot, in the sense of Fritsch and Carlson (1980) and Hyman (1983). With d_l
// and d_r the secants (position change over time) of the intervals left and right of the knot:
//   - both of one sign (locally monotone): the slope has that sign and at most 3 min(|d_l|, |d_r|);
//   - one of them zero (the axis stands on that side) or of opposite signs (a reading where the
//     axis turns back): slope 0;
//   - at a session's end, the one secant: its sign, at most 3 times it.
// With every knot's slope so bounded the Hermite on each interval is monotone, so it stays within
// its two readings. Each bound is then widened by 4 tol / h (h: the longer of the knot's
// intervals), which moves the curve by at most tol on either interval: on a densely sampled log (h
// a few ms) the widening is a few mm/s or deg/s and leaves the least-squares slope alone, so
// position quantisation (a slow axis whose readings repeat) does not become velocity ripple and a
// motion that turns smoothly between readings keeps its slope; across sparse readings (h of tenths
// of a second) it is the plain limit.
struct SlopeLimit {
    bool rotary = true;
    bool linear = true;
    // Linear axes only at a knot with an interval longer than this: the 50 ms above which a polled
    // log's silence is a `gap`. Across sparse readings (an event-driven log's, a gap) the cubic
    // throws the tool past where it stopped by some 7 % of the move (0.74 mm past a 10 mm move
    // between reports 0.3 s apart), into material it never reached. Between a polled log's readings a few ms apart it
    // departs by some um (18 um below the readings where X reverses at 6.17 s in the demo log;
    // limiting there too would move the demo's velocities by up to 14 mm/s), and the force
    // results validated on those logs (docs/force_model.md, docs/ingest.md) stay as they were.
    double linear_min_interval_s = 0.05;
    double tol_mm = 0.005;                     // half the step above which positions count as coarse
    double tol_deg = 0.005 / kRotaryMmPerDeg;  // the same at 100 mm from the axis line (0.0029 deg)
};

// The limited slope at a knot; d_left / d_right absent (nullopt) at a session's ends. h_max: the
// longer of the knot's intervals (s).
double limit_slope(double slope, std::optional<double> d_left, std::optional<double> d_right, double h_max, double tol);

// Accepts sessions and ticks; emits sessions and knots. The velocity at a tick is the
// least-squares slope of position over the ticks within +-2T of it (T: the CNC period the tick
// was timed with), and at least its two neighbours; one-sided at the ends of a session. With
// readings at their ticks this is exact for constant feed; the window of 4 to 5 CNC periods
// averages position quantisation as eqs. 4.1/4.2 average over three. Without a grid (T = 0) the
// window is the two neighbours: eqs. 4.1/4.2 themselves. A knot is emitted once the ticks
// within its window have arrived.
//
// The slope is then limited (SlopeLimit) so that the cubic Hermite the resample stage draws
// between two knots does not leave the range of their positions: a machine does not travel past
// where it stops. Without the limit an index reported by
// sparse readings (B 0 -> 180 deg between two reports, standing before and after) overshoots by
// 15 deg either side, because the slope at the last standing knot already points into the move.
class Velocity final : public Stage {
public:
    explicit Velocity(const SlopeLimit& limit = SlopeLimit{}) : Stage("velocity"), limit_(limit) {}
    Flows accepts() const override { return Flow::Sessions | Flow::Ticks; }
    Flows emits() const override { return Flow::Sessions | Flow::Knots; }
    void begin_session() override;
    void tick(const Tick& t) override;
    void end_session(SessionSummary& s) override;

private:
    void finalise(bool final);
    void fit(std::size_t j, double half_window_s);
    void limit(std::size_t j);

    SlopeLimit limit_;
    std::deque<Knot> knots_;       // the window around knots_[next_]
    std::size_t next_ = 0;         // first knot without a velocity
    double period_s_ = 0;
};

}  // namespace cutload::motion_io::detail
