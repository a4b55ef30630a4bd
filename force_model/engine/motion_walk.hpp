// Internal: the walk along the motion model. Sessions are separate stretches; within one, each
// motion interval [i, i + 1] yields time steps at the angles k * angle_step of the log's own
// spindle angle (docs/force_model.md, "Time steps, batches and air"). Nothing here knows the stock
// or the tool's shape: a step is the tool tip's position, velocity and angle.
#pragma once

#include "engine/vec3.hpp"

#include "motion_io/hermite.hpp"
#include "motion_io/motion_io.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <utility>
#include <vector>

namespace cutload::force_model {

// The sessions as [begin, end) sample ranges; a model without a session list is one session.
std::vector<std::pair<std::size_t, std::size_t>> session_ranges(const motion_io::MotionModel& m);

// Motion time actually simulated: the sum of the sessions' spans (time may jump between them).
double simulated_seconds(const motion_io::MotionModel& m);

// One row per angle step plus one per motion sample: an upper bound that avoids regrowing rows.
std::size_t expected_rows(const motion_io::MotionModel& m, double angle_step_deg);

// The tool tip at sample i in stock coordinates (the run spec's offset added).
Vec3 tip_position(const motion_io::MotionModel& m, std::size_t i, const double offset_mm[3]);
double speed_mm_s(const motion_io::MotionModel& m, std::size_t i);

// The tool at one spindle angle.
struct TimeStep {
    double t_s = 0, angle_deg = 0, theta_rad = 0;
    Vec3 tip_mm;                 // tool tip, stock coordinates
    Vec3 velocity_mm_s;
    double speed_mm_s = 0;
    Vec3 feed_per_tooth_mm;      // velocity * 60 / (flutes |rpm|)
    double rpm = 0;
    std::int32_t block = -1;
    double cos_a = 1, sin_a = 0;   // of A = pi/2 - theta: flute 0's direction, for the kernels
};

// The time steps of one motion interval with the spindle turning one way at both ends (|rpm| >= 1).
// The time of a step solves the quadratic angle(t) (spindle speed linear between samples); position
// and velocity come from the motion's cubic Hermite (motion_io::HermiteSegment) as polynomials in
// u = dt / h, so a step costs no division; cos and sin of A advance by an exact rotation of one
// angle step, seeded once per interval.
class IntervalSteps {
public:
    IntervalSteps(const motion_io::MotionModel& m, std::size_t i, const double offset_mm[3], double angle_step_deg,
                  int flutes);
    bool empty() const { return done(first_angle_index_ * step_deg_); }
    double spin() const { return spin_; }   // +1 M03, -1 M04
    // Every step keeps the first sample's block (normally the later half of the interval takes the
    // next sample's): at a tool change the interval is the old tool's, and so is its block.
    void keep_first_block() { block1_ = block0_; }
    // The next step; false after the last one.
    bool next(TimeStep& s);

private:
    bool done(double angle_deg) const { return spin_ > 0 ? angle_deg >= a1_deg_ : angle_deg <= a1_deg_; }

    double t0_s_, h_s_, inv_h_, a0_deg_, a1_deg_, rpm0_, rpm1_, step_deg_, spin_;
    double angle_index_, first_angle_index_;   // the next step is at angle_index_ * step_deg_
    double qa_, qb_, inv_qb_;   // angle(dt) - a0 = qa dt^2 + qb dt
    bool constant_speed_;
    double c0_[3], c1_[3], c2_[3], c3_[3], d0_[3], d1_[3], d2_[3];   // position and velocity polynomials
    double tooth_factor_, per_tooth_const_;
    double cos_a_, sin_a_, rot_c_, rot_s_;
    std::int32_t block0_, block1_;
};

inline bool IntervalSteps::next(TimeStep& s) {
    const double ak = angle_index_ * step_deg_;
    if (done(ak)) return false;
    const double da = ak - a0_deg_;
    double dt;
    if (constant_speed_) {
        dt = da * inv_qb_;
    } else {
        const double disc = std::max(0.0, qb_ * qb_ + 4 * qa_ * da);
        dt = 2 * da / (qb_ + std::copysign(std::sqrt(disc), qb_));
    }
    dt = std::clamp(dt, 0.0, h_s_);
    const double u = dt * inv_h_;
    s.t_s = t0_s_ + dt;
    s.angle_deg = ak;
    s.theta_rad = ak * (std::numbers::pi / 180);
    s.tip_mm = {((c3_[0] * u + c2_[0]) * u + c1_[0]) * u + c0_[0], ((c3_[1] * u + c2_[1]) * u + c1_[1]) * u + c0_[1],
                ((c3_[2] * u + c2_[2]) * u + c1_[2]) * u + c0_[2]};
    const Vec3 v{(d2_[0] * u + d1_[0]) * u + d0_[0], (d2_[1] * u + d1_[1]) * u + d0_[1],
                 (d2_[2] * u + d1_[2]) * u + d0_[2]};
    s.velocity_mm_s = v;
    s.rpm = rpm0_ + (rpm1_ - rpm0_) * u;
    s.block = u < 0.5 ? block0_ : block1_;
    s.speed_mm_s = norm3(v.x, v.y, v.z);
    const double per_tooth = constant_speed_ ? per_tooth_const_ : tooth_factor_ / std::abs(s.rpm);
    s.feed_per_tooth_mm = {v.x * per_tooth, v.y * per_tooth, v.z * per_tooth};
    s.cos_a = cos_a_;
    s.sin_a = sin_a_;
    const double c_next = cos_a_ * rot_c_ - sin_a_ * rot_s_;
    sin_a_ = sin_a_ * rot_c_ + cos_a_ * rot_s_;
    cos_a_ = c_next;
    angle_index_ += spin_;
    return true;
}

}  // namespace cutload::force_model
