// Stage "velocity": least-squares slope over +-2T around each tick (eqs. 4.1/4.2 generalised).
#include "stage_rig.hpp"
#include "stages/velocity.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <functional>

using namespace cutload::motion_io;
using namespace cutload::motion_io::test;

namespace {

struct VelocityRig {
    StageRig rig{std::make_unique<detail::Velocity>(), Flow::Sessions | Flow::Ticks, Flow::Sessions | Flow::Knots};
    void run(const std::vector<double>& times, const std::function<double(double)>& x, double period_s) {
        rig.feeder->begin();
        for (double t : times) {
            detail::Tick k;
            k.t_s = t;
            k.p_mm[0] = x(t);
            k.p_mm[1] = -2 * x(t);
            k.period_s = period_s;
            rig.feeder->tick(k);
        }
        detail::SessionSummary s;
        s.period_s = period_s;
        rig.feeder->end(s);
    }
    const std::vector<detail::Knot>& knots() const { return rig.out->knots; }
};

std::vector<double> grid_times(int n, double step, double t0 = 0.1) {
    std::vector<double> t;
    for (int i = 0; i < n; ++i) t.push_back(t0 + step * i);
    return t;
}

}  // namespace

TEST_CASE("velocity: constant feed is exact at every tick, ends included", "[velocity]") {
    VelocityRig v;
    // Ticks 1 or 2 periods apart, as 6 ms reads on a 4 ms grid give them.
    std::vector<double> t;
    for (int i = 0, n = 0; i < 60; ++i, n += 1 + i % 2) t.push_back(0.2 + 0.004 * n);
    v.run(t, [](double s) { return 7.0 + 100.0 * s; }, 0.004);
    REQUIRE(v.knots().size() == 60);
    for (const auto& k : v.knots()) {
        CHECK(k.v_mm_s[0] == Approx(100.0).epsilon(1e-9));
        CHECK(k.v_mm_s[1] == Approx(-200.0).epsilon(1e-9));
    }
}

TEST_CASE("velocity: inside the session a symmetric window gives a quadratic motion's exact slope", "[velocity]") {
    VelocityRig v;
    const double a = 500.0;   // mm/s^2
    const double T = 1.0 / 256;   // exact in binary: the window's edges fall on ticks
    v.run(grid_times(40, T, 0.125), [&](double s) { return 0.5 * a * s * s; }, T);
    REQUIRE(v.knots().size() == 40);
    // +-2T: five ticks, symmetric from the third to the third last.
    for (std::size_t i = 2; i + 2 < 40; ++i) CHECK(v.knots()[i].v_mm_s[0] == Approx(a * v.knots()[i].t_s).epsilon(1e-9));
    // One-sided at the start: ticks 0..2 around tick 0, whose slope is the fit's, a*(t0 + T).
    CHECK(v.knots()[0].v_mm_s[0] == Approx(a * (0.125 + T)).epsilon(1e-9));
}

TEST_CASE("velocity: without a grid the window is the two neighbours (eqs. 4.1/4.2)", "[velocity]") {
    VelocityRig v;
    const std::vector<double> t{0.0, 0.005, 0.013, 0.017, 0.030};
    auto x = [](double s) { return std::sin(20 * s); };
    v.run(t, x, 0.0);
    REQUIRE(v.knots().size() == 5);
    // Least squares through three points, written out: slope = sum (t - mt)(x - mx) / sum (t - mt)^2.
    for (std::size_t j = 1; j + 1 < t.size(); ++j) {
        const double mt = (t[j - 1] + t[j] + t[j + 1]) / 3, mx = (x(t[j - 1]) + x(t[j]) + x(t[j + 1])) / 3;
        double sxy = 0, sxx = 0;
        for (std::size_t i = j - 1; i <= j + 1; ++i) sxy += (t[i] - mt) * (x(t[i]) - mx), sxx += (t[i] - mt) * (t[i] - mt);
        CHECK(v.knots()[j].v_mm_s[0] == Approx(sxy / sxx).epsilon(1e-12));
    }
    // The ends: the slope of the two-point line.
    CHECK(v.knots()[0].v_mm_s[0] == Approx((x(t[1]) - x(t[0])) / (t[1] - t[0])).epsilon(1e-12));
}

TEST_CASE("velocity: a tick beyond 2T does not enter the fit, knots come out once their window is complete",
          "[velocity]") {
    // Times exact in binary (a 1/256 s period), so that "within 2T" has no rounding at its edge.
    const double T = 1.0 / 256;
    VelocityRig a, b;
    auto straight = [](double s) { return 50.0 * s; };
    auto bent = [&](double s) { return s > 0.125 + 12.5 * T ? 50.0 * s + 3.0 : 50.0 * s; };   // moves ticks 13..
    a.run(grid_times(30, T, 0.125), straight, T);
    b.run(grid_times(30, T, 0.125), bent, T);
    CHECK(b.knots()[10].v_mm_s[0] == a.knots()[10].v_mm_s[0]);   // tick 13 is 3T from tick 10
    CHECK(b.knots()[11].v_mm_s[0] != a.knots()[11].v_mm_s[0]);   // and exactly 2T from tick 11

    VelocityRig live;
    live.rig.feeder->begin();
    for (int i = 0; i < 10; ++i) {
        detail::Tick k;
        k.t_s = T * i;
        k.period_s = T;
        live.rig.feeder->tick(k);
    }
    CHECK(live.knots().size() == 8);   // the last two wait for ticks within 2T after them
}

TEST_CASE("velocity: a tick that replaces the one before moves it before its slope is taken", "[velocity]") {
    VelocityRig v;
    v.rig.feeder->begin();
    auto tick = [&](double t, double x, bool replace) {
        detail::Tick k;
        k.t_s = t;
        k.p_mm[0] = x;
        k.replaces_previous = replace;
        v.rig.feeder->tick(k);
    };
    tick(0.0, 0.0, false);
    tick(0.01, 5.0, false);
    tick(0.01, 1.0, true);
    tick(0.02, 2.0, false);
    v.rig.feeder->end();
    REQUIRE(v.knots().size() == 3);
    CHECK(v.knots()[1].p_mm[0] == 1.0);
    CHECK(v.knots()[1].v_mm_s[0] == Approx(100.0));
}
