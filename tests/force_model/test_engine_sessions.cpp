// Sessions: a motion model made of several logging sessions, between which the tool "teleports" and
// time may jump forwards or backwards. Nothing is interpolated or removed across a boundary.
#include "force_model/engine.hpp"
#include "force_model/engine_fixtures.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <numbers>

using namespace cutload;
using namespace cutload::enginetest;
using force_model::Device;

namespace {

// Appends `b` to `a` as a new session whose clock starts at t_start_s.
motion_io::MotionModel concat_sessions(motion_io::MotionModel a, const motion_io::MotionModel& b, double t_start_s) {
    const std::size_t first = a.size();
    const auto block_offset = std::int32_t(a.block_names.size());
    a.session_start.push_back(first);
    for (std::size_t i = 0; i < b.size(); ++i) {
        a.t_s.push_back(t_start_s + b.t_s[i] - b.t_s.front());
        a.x_mm.push_back(b.x_mm[i]);
        a.y_mm.push_back(b.y_mm[i]);
        a.z_mm.push_back(b.z_mm[i]);
        a.vx_mm_s.push_back(b.vx_mm_s[i]);
        a.vy_mm_s.push_back(b.vy_mm_s[i]);
        a.vz_mm_s.push_back(b.vz_mm_s[i]);
        a.spindle_rpm.push_back(b.spindle_rpm[i]);
        a.spindle_angle_deg.push_back(b.spindle_angle_deg[i]);
        a.block.push_back(b.block[i] + block_offset);
    }
    a.block_names.insert(a.block_names.end(), b.block_names.begin(), b.block_names.end());
    return a;
}

}  // namespace

TEST_CASE("sessions: no interpolation or removal across a session boundary") {
    const auto spec = base_spec();   // 40 x 20 x 10 box
    // Session 1 slots 3 mm deep into the box from the left and stops at x = 5; session 2 starts
    // inside the material at x = 35 (the tool "teleports") and leaves on the right. Its clock
    // starts 0.2 s before session 1 ended: time goes backwards across the boundary.
    const auto s1 = legs_motion({-10, 10, 7}, {{{5, 10, 7}, 3000, "s1"}});
    const auto s2 = legs_motion({35, 10, 7}, {{{50, 10, 7}, 3000, "s2"}});
    const auto m = concat_sessions(s1, s2, s1.t_s.back() - 0.2);
    REQUIRE(m.session_start.size() == 2);

    std::vector<Device> devices{Device::Cpu};
    if (opencl_available()) devices.push_back(Device::OpenCL);
    for (Device device : devices) {
        force_model::PredictOptions o;
        o.device = device;
        const auto p = force_model::predict(m, spec, o);
        const auto& st = *p.final_stock;
        // Between the sessions' ends the slot's centre line is untouched.
        for (int i = 100; i <= 300; i += 20) CHECK(kernels::ray_top(st.ray(i, 100)) == Approx(10));
        CHECK(kernels::ray_top(st.ray(20, 100)) == Approx(7));    // x 2: cut by session 1
        CHECK(kernels::ray_top(st.ray(380, 100)) == Approx(7));   // x 38: cut by session 2
        // Each session removes a 3 mm deep slot of 5 mm full width plus a half disc of radius 4.
        const double area = 5 * 8 + std::numbers::pi * 16 / 2;
        const double removed = 40 * 20 * 10 - force_model::stock_volume_mm3(st);
        CHECK(removed == Approx(2 * 3 * area).epsilon(0.02));
        // Session 2's rows stay inside its own time span, and their forces are those of a slot
        // entered at 50 mm/s, not of a jump across 30 mm.
        const double t2_begin = m.t_s[m.session_start[1]], t2_end = m.t_s.back();
        double peak_s2 = 0;
        for (const auto& s : p.samples) {
            if (s.block != 1) continue;
            CHECK(s.t_s >= t2_begin);
            CHECK(s.t_s <= t2_end);
            peak_s2 = std::max(peak_s2, double(std::hypot(s.fx_N, s.fy_N, s.fz_N)));
        }
        CHECK(peak_s2 > 100);
        CHECK(peak_s2 < 2 * p.blocks[0].peak_force_N);
        // Simulated time is the sum of the sessions' spans, not last minus first time stamp.
        CHECK(p.stats.simulated_s == Approx((s1.t_s.back() - s1.t_s.front()) + (s2.t_s.back() - s2.t_s.front())));
    }
}

TEST_CASE("sessions: a malformed session list is rejected") {
    const auto spec = base_spec();
    auto m = legs_motion({-10, 10, 7}, {{{5, 10, 7}, 3000, "s1"}});
    m.session_start = {0, m.size() + 3};
    force_model::PredictOptions o;
    o.device = Device::Cpu;
    CHECK_THROWS_WITH(force_model::predict(m, spec, o), Catch::Contains("session_start"));
    m.session_start = {0, 20, 10};
    CHECK_THROWS_WITH(force_model::predict(m, spec, o), Catch::Contains("session_start"));
}
