#include "stages/spindle.hpp"

namespace cutload::motion_io::detail {

void SpindleAngle::begin_session() {
    readings_.clear();
    have_prev_ = false;
    angle_deg_ = 0;
    emit_begin_session();
}

void SpindleAngle::grid(std::span<GridSample> batch) {
    for (GridSample& s : batch) {
        s.spindle_rpm = rpm_at(s.t_s);
        // Trapezoid rule: exact for the linear speed that sample_between() assumes.
        if (have_prev_) angle_deg_ += 6.0 * 0.5 * (prev_rpm_ + s.spindle_rpm) * step_s_;
        have_prev_ = true;
        prev_rpm_ = s.spindle_rpm;
        s.spindle_angle_deg = angle_deg_;
    }
    emit(batch);
}

double SpindleAngle::rpm_at(double t_s) {
    while (readings_.size() >= 2 && readings_[1].first <= t_s) readings_.pop_front();
    if (readings_.empty()) return 0;
    const auto& [t0, r0] = readings_[0];
    if (readings_.size() == 1 || t_s <= t0) return r0;
    const auto& [t1, r1] = readings_[1];
    return t1 > t0 ? r0 + (r1 - r0) * (t_s - t0) / (t1 - t0) : r1;
}

}  // namespace cutload::motion_io::detail
