// The cubic Hermite segment that every C1 motion in cutload is made of: the ingest stages resample
// the log with it, the motion model interpolates between its samples with it, the force engine
// walks it step by step and the feed optimiser re-times it. One definition, so all of them agree
// on where the tool is between two samples.
#pragma once

#include <array>

namespace cutload::motion_io {

// Position p0 -> p1 over an interval of h seconds, with velocities v0 and v1 at its ends (per
// second). u = (t - t0) / h runs from 0 to 1. One axis; callers loop over axes.
struct HermiteSegment {
    double p0 = 0, v0 = 0, p1 = 0, v1 = 0, h = 0;

    double position(double u) const {
        const double u2 = u * u, u3 = u2 * u;
        const double h00 = 2 * u3 - 3 * u2 + 1, h10 = u3 - 2 * u2 + u, h01 = -2 * u3 + 3 * u2, h11 = u3 - u2;
        return h00 * p0 + h10 * h * v0 + h01 * p1 + h11 * h * v1;
    }
    // d position / dt (not / du). A zero-length segment has the start velocity.
    double velocity(double u) const {
        if (!(h > 0)) return v0;
        const double u2 = u * u;
        const double d00 = 6 * u2 - 6 * u, d10 = 3 * u2 - 4 * u + 1, d01 = -6 * u2 + 6 * u, d11 = 3 * u2 - 2 * u;
        return (d00 * p0 + d01 * p1) / h + d10 * v0 + d11 * v1;
    }
    // The same curve as a polynomial in u: position = c[0] + c[1] u + c[2] u^2 + c[3] u^3
    // (for walking many steps of one segment without re-evaluating the basis).
    std::array<double, 4> coefficients() const {
        return {p0, h * v0, 3 * (p1 - p0) - h * (2 * v0 + v1), 2 * (p0 - p1) + h * (v0 + v1)};
    }
};

}  // namespace cutload::motion_io
