// Internal: stage "velocity" - the velocity of the motion at each tick.
#pragma once

#include "stages/stage.hpp"

#include <deque>

namespace cutload::motion_io::detail {

// Accepts sessions and ticks; emits sessions and knots. The velocity at a tick is the
// least-squares slope of position over the ticks within +-2T of it (T: the CNC period the tick
// was timed with), and at least its two neighbours; one-sided at the ends of a session. With
// readings at their ticks this is exact for constant feed; the window of 4 to 5 CNC periods
// averages position quantisation as eqs. 4.1/4.2 average over three. Without a grid (T = 0) the
// window is the two neighbours: eqs. 4.1/4.2 themselves. A knot is emitted once the ticks
// within its window have arrived.
class Velocity final : public Stage {
public:
    Velocity() : Stage("velocity") {}
    Flows accepts() const override { return Flow::Sessions | Flow::Ticks; }
    Flows emits() const override { return Flow::Sessions | Flow::Knots; }
    void begin_session() override;
    void tick(const Tick& t) override;
    void end_session(SessionSummary& s) override;

private:
    void finalise(bool final);
    void fit(std::size_t j, double half_window_s);

    std::deque<Knot> knots_;       // the window around knots_[next_]
    std::size_t next_ = 0;         // first knot without a velocity
    double period_s_ = 0;
};

}  // namespace cutload::motion_io::detail
