// The one cubic Hermite segment (motion_io/hermite.hpp) that ingest, the motion model, the engine
// and the feed optimiser share: checked against a cubic written out by hand.
#include "motion_io/hermite.hpp"

#include <catch2/catch.hpp>

#include <cmath>

using cutload::motion_io::HermiteSegment;

TEST_CASE("hermite: a segment reproduces any cubic from its end positions and velocities") {
    // p(t) = 2 - 3 t + 0.5 t^2 + 4 t^3 over t in [0, h], h = 0.004 s (one CNC period).
    const double h = 0.004;
    auto p = [](double t) { return 2 - 3 * t + 0.5 * t * t + 4 * t * t * t; };
    auto v = [](double t) { return -3 + t + 12 * t * t; };
    const HermiteSegment seg{p(0), v(0), p(h), v(h), h};
    for (double u : {0.0, 0.1, 0.37, 0.5, 0.9, 1.0}) {
        const double t = u * h;
        CHECK(seg.position(u) == Approx(p(t)).epsilon(1e-14));
        CHECK(seg.velocity(u) == Approx(v(t)).epsilon(1e-12));
        const auto c = seg.coefficients();
        CHECK(c[0] + c[1] * u + c[2] * u * u + c[3] * u * u * u == Approx(p(t)).epsilon(1e-14));
    }
}

TEST_CASE("hermite: a zero-length segment stands still at its start velocity") {
    const HermiteSegment seg{5.0, 100.0, 5.0, 120.0, 0.0};
    CHECK(seg.position(0.0) == 5.0);
    CHECK(seg.velocity(0.3) == 100.0);
}
