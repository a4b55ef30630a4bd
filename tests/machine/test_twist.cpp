// The tool-frame twist over an interval between two poses (document 000, eqs. 3.16-3.22):
// against omega x r worked out by hand for pure rotary moves, and against the thesis's own
// formulas (3.18, 3.19) evaluated with finely differenced poses for a combined move.
#include "machine/twist.hpp"
#include "machine_fixtures.hpp"

#include <catch2/catch.hpp>

#include <cmath>

using namespace cutload::machine;
using machine_fixtures::kDeg;

namespace {

void check_vec(const Eigen::Vector3d& got, const Eigen::Vector3d& want, double tol) {
    INFO("got (" << got.transpose() << "), want (" << want.transpose() << "), difference " << (got - want).norm());
    CHECK((got - want).norm() < tol);
}

}  // namespace

TEST_CASE("twist: a C-table turn moves each tool point at omega x r about the C line", "[machine]") {
    // BC head-table, B = 0: the tool stands still and the table turns from C = -0.5 to +0.5 deg.
    // Relative to the workpiece the tool turns +C (sense +1) about the C line through
    // (-600, -400) along Z. At the middle pose, C = 0, a point at P moves at
    // omega e_z x (P - pC) = omega (-(P - pC)_y, (P - pC)_x, 0).
    const Machine m = machine_fixtures::bc_head_table();
    const double L = 80, X = -500, Y = -400, Z = -250;
    const double rate_deg_s = 30;
    for (const double dt : {0.004, 0.006, 0.0017}) {   // unequal intervals: the same velocities
        const double half = rate_deg_s * dt / 2;
        const ToolPose p0 = forward(m, positions(m, {{'X', X}, {'Y', Y}, {'Z', Z}, {'C', -half}}), L);
        const ToolPose p1 = forward(m, positions(m, {{'X', X}, {'Y', Y}, {'Z', Z}, {'C', half}}), L);
        const Twist tw = interval_twist(p0.tool_to_workpiece, p1.tool_to_workpiece, dt);
        const Frame mid = advance(p0.tool_to_workpiece, tw, dt / 2);
        const double w = rate_deg_s * kDeg;   // 0.5236 rad/s
        // The tip: P - pC = (X, Y, Z - L) - (-600, -400, .) = (100, 0, .): v = (0, 100 w, 0) = 52.36 mm/s in Y.
        // Tolerance: positions of 600 mm carry a few 1e-12 mm of round-off, over a 1.7 ms interval
        // a few 1e-9 mm/s.
        INFO("dt = " << dt);
        check_vec(point_velocity_workpiece(mid, tw, Eigen::Vector3d::Zero()), Eigen::Vector3d(0, 100 * w, 0), 1e-7);
        // An edge point 4 mm out along tool x and 12 mm up (tool x = machine X at B = 0):
        // P - pC = (104, 0, .): v = (0, 104 w, 0). One 4 mm out along tool y: (100, 4, .):
        // v = w (-4, 100, 0).
        check_vec(point_velocity_workpiece(mid, tw, Eigen::Vector3d(4, 0, 12)), Eigen::Vector3d(0, 104 * w, 0), 1e-7);
        check_vec(point_velocity_workpiece(mid, tw, Eigen::Vector3d(0, 4, 12)), Eigen::Vector3d(-4 * w, 100 * w, 0), 1e-7);
        // In tool coordinates the turn is about the tool's own z.
        check_vec(tw.omega_rad_s, Eigen::Vector3d(0, 0, w), 1e-12);
    }
}

TEST_CASE("twist: a B-head turn moves the tip on a circle about the head pivot", "[machine]") {
    // BC head-table, B from 10 to 11 deg in 5 ms (200 deg/s); pivot 230 mm above the gauge point,
    // tool 100 mm: the tip hangs h = 330 mm below the pivot. At B the tip sits at
    // pivot + R_y(B) (0, 0, -h) = pivot + (-h sin B, 0, -h cos B), and moves at
    // omega e_y x (-h sin B, 0, -h cos B) = omega (-h cos B, 0, h sin B)
    // (e_y x (x, y, z) = (z, 0, -x)). A large step: the log map is exact for a constant-rate turn.
    const Machine m = machine_fixtures::bc_head_table();
    const double h = 330, dt = 0.005, w = 200 * kDeg;
    const std::map<char, double> base = {{'X', -700}, {'Y', -300}, {'Z', -120}};
    auto at_b = [&](double B) {
        auto q = base;
        q['B'] = B;
        return forward(m, positions(m, q), 100).tool_to_workpiece;
    };
    const Twist tw = interval_twist(at_b(10), at_b(11), dt);
    for (const double s : {0.0, 0.5, 1.0}) {
        const double B = (10 + s) * kDeg;
        const Frame at = advance(at_b(10), tw, s * dt);
        check_vec(at.origin_mm, at_b(10 + s).origin_mm, 1e-9);   // on the screw the pose is the machine's
        check_vec(point_velocity_workpiece(at, tw, Eigen::Vector3d::Zero()),
                  w * Eigen::Vector3d(-h * std::cos(B), 0, h * std::sin(B)), 1e-8);
    }
    // A point 5 mm off the axis along tool x and 20 mm up: at B it is
    // R_y(B) (5, 0, 20 - h) from the pivot, i.e. (5 cos B + (20 - h) sin B, 0, -5 sin B + (20 - h) cos B),
    // and moves at omega e_y x that = omega (z, 0, -x).
    const double B = 10.5 * kDeg;
    const double rx = 5 * std::cos(B) + (20 - h) * std::sin(B), rz = -5 * std::sin(B) + (20 - h) * std::cos(B);
    check_vec(point_velocity_workpiece(advance(at_b(10), tw, dt / 2), tw, Eigen::Vector3d(5, 0, 20)),
              w * Eigen::Vector3d(rz, 0, -rx), 1e-8);
}

TEST_CASE("twist: a combined move matches the thesis's tau and omega (eqs. 3.18, 3.19) at mid-interval", "[machine]") {
    // AC table-table moving X, Y, Z, A and C together along smooth curves. The reference is
    // eq. 3.18 tau = A^T dr/dt and eq. 3.19 omega = skew part of A^T dA/dt, with the derivatives
    // taken by central differences (h = 1e-6 s) at the interval's middle. The interval twist
    // differs from it by O(dt^2): halving dt must cut the difference about four times.
    const Machine m = machine_fixtures::ac_table_table();
    auto pose = [&](double t) {
        return forward(m, positions(m, {{'X', -300 + 150 * t + 40 * t * t}, {'Y', -200 - 60 * t},
                                        {'Z', -180 + 30 * t * t}, {'A', -20 - 45 * t + 10 * t * t},
                                        {'C', 30 + 120 * t - 35 * t * t * t}}),
                       110)
            .tool_to_workpiece;
    };
    const double t_mid = 0.37, hd = 1e-6;
    const Frame fm = pose(t_mid), fp = pose(t_mid + hd), fn = pose(t_mid - hd);
    const Eigen::Vector3d r_dot = (fp.origin_mm - fn.origin_mm) / (2 * hd);
    const Eigen::Matrix3d A_dot = (fp.R - fn.R) / (2 * hd);
    const Eigen::Vector3d tau = fm.R.transpose() * r_dot;                  // eq. 3.18
    const Eigen::Matrix3d AtAd = fm.R.transpose() * A_dot;                 // eq. 3.22
    const Eigen::Vector3d omega((AtAd(2, 1) - AtAd(1, 2)) / 2, (AtAd(0, 2) - AtAd(2, 0)) / 2,
                                (AtAd(1, 0) - AtAd(0, 1)) / 2);            // eq. 3.19
    double diff_prev = 0;
    for (const double dt : {0.008, 0.004, 0.002}) {
        const Frame f0 = pose(t_mid - dt / 2), f1 = pose(t_mid + dt / 2);
        const Twist tw = interval_twist(f0, f1, dt);
        // Compare at the middle pose; the edge point 6 mm out and 15 mm up feels both parts.
        const Eigen::Vector3d r(6, 0, 15);
        const Eigen::Vector3d v_ref = tau + omega.cross(r);
        const Eigen::Vector3d v = point_velocity(tw, r);
        const double diff = (v - v_ref).norm() + (tw.omega_rad_s - omega).norm() * 100;
        INFO("dt = " << dt << ": |v| = " << v_ref.norm() << " mm/s, difference " << diff);
        CHECK(diff < 1e-4 * v_ref.norm());
        if (diff_prev > 0) {
            CHECK(diff_prev / diff > 3.5);
            CHECK(diff_prev / diff < 4.5);
        }
        diff_prev = diff;
        // The screw carries the first pose onto the second exactly.
        const Frame end = advance(f0, tw, dt);
        CHECK((end.origin_mm - f1.origin_mm).norm() < 1e-10);
        CHECK((end.R - f1.R).norm() < 1e-13);
    }
}

TEST_CASE("twist: a zero or negative interval is refused", "[machine]") {
    const Frame f;
    CHECK_THROWS_AS(interval_twist(f, f, 0), std::invalid_argument);
    CHECK_THROWS_AS(interval_twist(f, f, -0.004), std::invalid_argument);
    const Twist still = interval_twist(f, f, 0.004);
    CHECK(still.v_mm_s.norm() == 0);
    CHECK(still.omega_rad_s.norm() == 0);
}
