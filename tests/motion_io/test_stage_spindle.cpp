// Stage "spindle_angle": speed interpolated between readings, angle by the trapezoid rule.
#include "stage_rig.hpp"
#include "stages/spindle.hpp"

#include <catch2/catch.hpp>

using namespace cutload::motion_io;
using namespace cutload::motion_io::test;

namespace {

struct SpindleRig {
    explicit SpindleRig(double step_s)
        : step(step_s), rig{std::make_unique<detail::SpindleAngle>(step_s), Flow::Sessions | Flow::Spindle | Flow::Grid,
                            Flow::Sessions | Flow::Grid} {}
    double step;
    StageRig rig;
    void grid(double t0, int n) {
        for (int i = 0; i < n; ++i) {
            detail::GridSample s;
            s.t_s = t0 + step * i;
            rig.feeder->grid(s);
        }
    }
    const std::vector<detail::GridSample>& samples() const { return rig.out->samples; }
};

}  // namespace

TEST_CASE("spindle_angle: a linear run-up is interpolated exactly and its angle is the closed-form integral",
          "[spindle]") {
    SpindleRig s(0.001);
    s.rig.feeder->begin();
    // 0 -> 12000 rpm over 0.5 s, read at uneven times (each reading on the ramp).
    for (double t : {0.0, 0.013, 0.2, 0.35, 0.5}) s.rig.feeder->session_record(value(Chan::Spindle, t, 24000 * t));
    s.rig.feeder->session_record(value(Chan::Spindle, 0.9, 12000));
    s.grid(0.0, 501);
    REQUIRE(s.samples().size() == 501);
    for (const auto& g : s.samples()) {
        CHECK(g.spindle_rpm == Approx(24000 * g.t_s).margin(1e-6));
        // angle = 6 deg/rev/s * integral of rpm dt = 6 * 12000 t^2 (starting at the first sample)
        CHECK(g.spindle_angle_deg == Approx(6 * 12000 * g.t_s * g.t_s).margin(1e-6));
    }
}

TEST_CASE("spindle_angle: speed held before the first and after the last reading, 0 without any", "[spindle]") {
    SpindleRig s(0.01);
    s.rig.feeder->begin();
    s.grid(0.0, 2);   // no reading yet
    s.rig.feeder->session_record(value(Chan::Spindle, 0.05, -3000));   // M04
    s.rig.feeder->session_record(value(Chan::Spindle, 0.06, -3000));
    s.grid(0.02, 8);
    CHECK(s.samples()[0].spindle_rpm == 0);
    CHECK(s.samples()[2].spindle_rpm == -3000);   // 0.02 s: before the first reading, held
    CHECK(s.samples()[9].spindle_rpm == -3000);   // 0.09 s: after the last
    CHECK(s.samples()[9].spindle_angle_deg == Approx(-6 * 3000 * 0.07 - 6 * 0.5 * 3000 * 0.01));
}

TEST_CASE("spindle_angle: each session's angle starts at 0 and forgets the readings before", "[spindle]") {
    SpindleRig s(0.01);
    s.rig.feeder->begin();
    s.rig.feeder->session_record(value(Chan::Spindle, 0.0, 6000));
    s.grid(0.0, 3);
    s.rig.feeder->end();
    s.rig.feeder->begin();
    s.grid(1.0, 2);
    CHECK(s.samples()[2].spindle_angle_deg == Approx(6 * 6000 * 0.02));
    CHECK(s.samples()[3].spindle_angle_deg == 0);
    CHECK(s.samples()[4].spindle_rpm == 0);
}
