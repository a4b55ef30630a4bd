#include "engine/motion_walk.hpp"

namespace cutload::force_model {

std::vector<std::pair<std::size_t, std::size_t>> session_ranges(const motion_io::MotionModel& m) {
    std::vector<std::size_t> starts = m.session_start;
    if (starts.empty() || starts.front() != 0) starts.insert(starts.begin(), 0);
    std::vector<std::pair<std::size_t, std::size_t>> out;
    for (std::size_t s = 0; s < starts.size(); ++s) out.emplace_back(starts[s], s + 1 < starts.size() ? starts[s + 1] : m.size());
    return out;
}

double simulated_seconds(const motion_io::MotionModel& m) {
    double total = 0;
    for (const auto& [b, e] : session_ranges(m))
        if (e > b + 1) total += m.t_s[e - 1] - m.t_s[b];
    return total;
}

std::size_t expected_rows(const motion_io::MotionExtent& extent, double angle_step_deg) {
    return std::size_t(extent.spindle_turned_deg / angle_step_deg) + extent.samples + 1;
}

std::size_t expected_rows(const motion_io::MotionModel& m, double angle_step_deg) {
    return expected_rows(motion_io::motion_extent(m), angle_step_deg);
}

Vec3 tip_position(const motion_io::MotionModel& m, std::size_t i, const double offset_mm[3]) {
    return {m.x_mm[i] + offset_mm[0], m.y_mm[i] + offset_mm[1], m.z_mm[i] + offset_mm[2]};
}

double speed_mm_s(const motion_io::MotionModel& m, std::size_t i) { return norm3(m.vx_mm_s[i], m.vy_mm_s[i], m.vz_mm_s[i]); }

IntervalSteps::IntervalSteps(const motion_io::MotionModel& m, std::size_t i, const double offset_mm[3],
                             double angle_step_deg, int flutes)
    : t0_s_(m.t_s[i]), h_s_(m.t_s[i + 1] - m.t_s[i]), a0_deg_(m.spindle_angle_deg[i]),
      a1_deg_(m.spindle_angle_deg[i + 1]), rpm0_(m.spindle_rpm[i]), rpm1_(m.spindle_rpm[i + 1]),
      step_deg_(angle_step_deg), spin_(rpm0_ > 0 ? 1.0 : -1.0), block0_(m.block[i]), block1_(m.block[i + 1]) {
    first_angle_index_ = angle_index_ = spin_ > 0 ? std::ceil(a0_deg_ / step_deg_) : std::floor(a0_deg_ / step_deg_);
    qa_ = 3 * (rpm1_ - rpm0_) / h_s_;
    qb_ = 6 * rpm0_;
    constant_speed_ = std::abs(qa_) * h_s_ * h_s_ < 1e-9 * std::abs(qb_) * h_s_;
    inv_qb_ = 1 / qb_;
    inv_h_ = 1 / h_s_;
    const std::vector<double>* position[3] = {&m.x_mm, &m.y_mm, &m.z_mm};
    const std::vector<double>* velocity[3] = {&m.vx_mm_s, &m.vy_mm_s, &m.vz_mm_s};
    for (int c = 0; c < 3; ++c) {
        const motion_io::HermiteSegment seg{(*position[c])[i] + offset_mm[c], (*velocity[c])[i],
                                            (*position[c])[i + 1] + offset_mm[c], (*velocity[c])[i + 1], h_s_};
        const auto poly = seg.coefficients();
        c0_[c] = poly[0];
        c1_[c] = poly[1];
        c2_[c] = poly[2];
        c3_[c] = poly[3];
        d0_[c] = seg.v0;
        d1_[c] = 2 * c2_[c] * inv_h_;
        d2_[c] = 3 * c3_[c] * inv_h_;
    }
    tooth_factor_ = 60.0 / flutes;
    per_tooth_const_ = tooth_factor_ / std::abs(rpm0_);
    // Seeded in double from the reduced angle, so the rotation's error stays at rounding.
    const double a_start = std::remainder(std::numbers::pi / 2 - angle_index_ * step_deg_ * std::numbers::pi / 180, 2 * std::numbers::pi);
    cos_a_ = std::cos(a_start);
    sin_a_ = std::sin(a_start);
    rot_c_ = std::cos(step_deg_ * std::numbers::pi / 180);
    rot_s_ = -spin_ * std::sin(step_deg_ * std::numbers::pi / 180);
}

}  // namespace cutload::force_model
