// Internal: stage "unwrap" - rotary axes as a continuous angle.
#pragma once

#include "stages/stage.hpp"

namespace cutload::motion_io::detail {

// Accepts and emits sessions and positions. A controller may display a rotary axis modulo 360 deg
// (a C table shown 0 to 360): a turn through 0 would read as a jump of almost a full turn, and the
// velocity and resampling downstream would sweep the table back round. Each rotary reading takes
// the 360-deg equivalent nearest the session's previous one, so an axis that moves less than
// 180 deg between readings (30 000 deg/s at 6 ms, beyond any table) is continuous. The first
// reading of a session keeps its value. Linear axes and logs without rotary axes pass unchanged.
class UnwrapRotary final : public Stage {
public:
    explicit UnwrapRotary(const ReaderFacts& facts) : Stage("unwrap"), facts_(facts) {}
    Flows accepts() const override { return Flow::Sessions | Flow::Positions; }
    Flows emits() const override { return Flow::Sessions | Flow::Positions; }
    void begin_session() override;
    void record(const Record& r) override;

private:
    const ReaderFacts& facts_;
    bool have_prev_ = false;
    double prev_deg_[3] = {0, 0, 0};
};

// The angle equivalent to `deg` modulo 360 nearest `previous_deg`; of two as near (an odd number of
// half turns away), the one nearer `deg` itself.
double nearest_equivalent_deg(double deg, double previous_deg);

}  // namespace cutload::motion_io::detail
