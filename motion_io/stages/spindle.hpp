// Internal: stage "spindle_angle" - spindle speed and angle at each grid sample.
#pragma once

#include "stages/stage.hpp"

#include <deque>
#include <utility>

namespace cutload::motion_io::detail {

// Accepts sessions, spindle readings and grid samples; emits sessions and grid samples with
// spindle speed and angle. The speed is interpolated linearly between readings (each at its own
// time stamp; held before the first and after the last, 0 rpm without any); the angle is its
// integral by the trapezoid rule over the grid step, which is exactly the quadratic angle that
// sample_between() assumes between samples. The angle starts at 0 in each session.
class SpindleAngle final : public Stage {
public:
    explicit SpindleAngle(double step_s) : Stage("spindle_angle"), step_s_(step_s) {}
    Flows accepts() const override { return Flow::Sessions | Flow::Spindle | Flow::Grid; }
    Flows emits() const override { return Flow::Sessions | Flow::Grid; }
    void begin_session() override;
    void record(const Record& r) override { readings_.emplace_back(r.t_s, r.v[0]); }
    void grid(std::span<GridSample> batch) override;

private:
    double rpm_at(double t_s);

    double step_s_;
    std::deque<std::pair<double, double>> readings_;   // (t_s, rpm) not yet passed by the grid
    bool have_prev_ = false;
    double prev_rpm_ = 0, angle_deg_ = 0;
};

}  // namespace cutload::motion_io::detail
