// Geometric errors (document 000, section 3.4.2) against closed forms worked out by hand, and the
// exact error chain against the thesis's first-order sum (eq. 3.43) written out with its 4x4
// matrices (eqs. 3.27, 3.32, 3.34, 3.40, 3.42).
#include "machine_fixtures.hpp"

#include <catch2/catch.hpp>

#include <cmath>

using namespace cutload::machine;
using machine_fixtures::kDeg;
using nlohmann::json;

namespace {

void check_vec(const Eigen::Vector3d& got, const Eigen::Vector3d& want, double tol) {
    INFO("got (" << got.transpose() << "), want (" << want.transpose() << "), difference " << (got - want).norm());
    CHECK((got - want).norm() < tol);
}

Eigen::Vector3d tip_shift(const Machine& m, const std::map<char, double>& q, double L) {
    const AxisPositions p = positions(m, q);
    return forward(m, p, L, ErrorMode::WithErrors).tip_mm() - forward(m, p, L, ErrorMode::Nominal).tip_mm();
}

}  // namespace

TEST_CASE("a squareness error and an A-C offset move the tip by the closed-form amount", "[machine]") {
    // Bundled AC trunnion, chain C A | Y X Z. Errors:
    //   EC0X = gamma = 50 urad: X (and Z and the tool it carries) turned about Z relative to Y,
    //     about the home origin: the X-Y squareness error;
    //   EY0C = delta = 20 um: the C line sits 20 um off the A line in Y.
    // By hand, with w = (X, Y, Z - L) the head's tip before the rotary axes:
    //   the squareness turns the X part of w: (X, 0, 0) -> (X cos g, X sin g, 0), a shift
    //     d1 = (X (cos g - 1), X sin g, 0); Y and Z are not turned (they sit before X or along Z);
    //   A turns d1 by R_x(A); the C line moved +delta in Y puts the tool -delta in Y relative to the
    //     table; C turns both by R_z(C):
    //   shift = R_z(C) [ (X (cos g - 1), X sin g cos A, X sin g sin A) - (0, delta, 0) ].
    Machine m = machine_fixtures::ac_table_table();
    set_errors(m, json::parse(R"({"X": {"EC0X_urad": 50}, "C": {"EY0C_um": 20}})"));
    const double g = 50e-6, delta = 0.020;
    for (const double X : {-400.0, -650.0, -25.0})
        for (const double A : {-30.0, 0.0, -100.0, 25.0})
            for (const double C : {90.0, 0.0, 217.0}) {
                const double a = A * kDeg, c = C * kDeg;
                const Eigen::Vector3d inner(X * (std::cos(g) - 1), X * std::sin(g) * std::cos(a) - delta,
                                            X * std::sin(g) * std::sin(a));
                const Eigen::Vector3d want(std::cos(c) * inner.x() - std::sin(c) * inner.y(),
                                           std::sin(c) * inner.x() + std::cos(c) * inner.y(), inner.z());
                INFO("X = " << X << ", A = " << A << ", C = " << C);
                check_vec(tip_shift(m, {{'X', X}, {'Y', -180}, {'Z', -240}, {'A', A}, {'C', C}}, 110), want, 1e-6);
                // Neither error turns the tool axis: the squareness turns about the axis itself.
                const AxisPositions p = positions(m, {{'X', X}, {'Y', -180}, {'Z', -240}, {'A', A}, {'C', C}});
                check_vec(forward(m, p, 110).axis(), forward(m, p, 110, ErrorMode::Nominal).axis(), 1e-15);
            }
    // The worked example of the comment, in numbers: X -400, A -30, C 90 ->
    // (0.02 + 0.02 cos 30, 5e-7, 0.01) mm = (0.0373205, 0.0000005, 0.0100000).
    check_vec(tip_shift(m, {{'X', -400}, {'Y', -180}, {'Z', -240}, {'A', -30}, {'C', 90}}, 110),
              Eigen::Vector3d(0.0373205081, 0.0000005, 0.0100000), 1e-9);
}

TEST_CASE("error signs: an axis's error moves what it carries, so a table axis moves the tool the other way", "[machine]") {
    // The same positioning error EXX = +5 um on an X axis in the head and on one under the table.
    // A head X that overshoots carries the tool +5 um; a table X that overshoots carries the
    // workpiece +5 um, which puts the tool -5 um relative to it.
    const char* head = R"({"code": "b X Y Z t", "errors": {"X": {"EXX_um": 5}}})";
    const char* table = R"({"code": "X b Y Z t", "errors": {"X": {"EXX_um": 5}}})";
    const Machine mh = parse_machine(json::parse(head));
    const Machine mt = parse_machine(json::parse(table));
    check_vec(tip_shift(mh, {{'X', -120}, {'Y', -40}, {'Z', -60}}, 80), Eigen::Vector3d(0.005, 0, 0), 1e-12);
    check_vec(tip_shift(mt, {{'X', -120}, {'Y', -40}, {'Z', -60}}, 80), Eigen::Vector3d(-0.005, 0, 0), 1e-12);
}

TEST_CASE("a linear axis's angular error acts about a point that travels with it (Abbe offset)", "[machine]") {
    // Yaw ECX = gamma of a head X axis carrying Y and Z, reference point at the home origin: the
    // point turns about (X, 0, 0), so the tip at (X, Y, Z - L) moves by the Abbe offset alone:
    // R_z(g) (0, Y, Z - L) - (0, Y, Z - L) = (-Y sin g, Y (cos g - 1), 0), whatever X is.
    const Machine m = parse_machine(json::parse(R"({"code": "b X Y Z t", "errors": {"X": {"ECX_urad": 30}}})"));
    const double g = 30e-6, Y = -250;
    for (const double X : {0.0, -300.0, -800.0})
        check_vec(tip_shift(m, {{'X', X}, {'Y', Y}, {'Z', -100}}, 100),
                  Eigen::Vector3d(-Y * std::sin(g), Y * (std::cos(g) - 1), 0), 1e-12);
    // Moving the reference point onto the tool's line removes the Abbe offset.
    const Machine at_tool = parse_machine(json::parse(
        R"({"code": "b X Y Z t", "errors": {"X": {"ECX_urad": 30, "reference_point_mm": [0, -250, -200]}}})"));
    check_vec(tip_shift(at_tool, {{'X', -300}, {'Y', Y}, {'Z', -100}}, 100), Eigen::Vector3d::Zero(), 1e-12);
}

TEST_CASE("an error table is interpolated at the axis position and turned with the table", "[machine]") {
    // EXX of the bundled error file: -450 mm lies halfway between 4.0 um (-500) and 3.1 um (-400).
    // The X stage sits after C and A, so its shift is turned by R_z(C) R_x(A); along X, R_x does
    // nothing and R_z(90) (d, 0, 0) = (0, d, 0).
    Machine m = machine_fixtures::ac_table_table();
    set_errors(m, json::parse(R"({"X": {"EXX_um": {"at_mm": [-700, -500, -400, 0], "values": [6.1, 4.0, 3.1, 0]}}})"));
    check_vec(tip_shift(m, {{'X', -450}, {'Y', -100}, {'Z', -100}}, 100), Eigen::Vector3d(3.55e-3, 0, 0), 1e-12);
    check_vec(tip_shift(m, {{'X', -450}, {'Y', -100}, {'Z', -100}, {'A', -40}, {'C', 90}}, 100),
              Eigen::Vector3d(0, 3.55e-3, 0), 1e-12);
}

TEST_CASE("the exact error chain agrees with the thesis's first-order sum (eq. 3.43)", "[machine]") {
    // A head-head machine with every axis on the tool side, chain X Y Z C A from the bed, rotary
    // axes through the origin. Here the thesis's placement and cutload's coincide: each axis's
    // error matrix sits immediately left of its motion matrix (eqs. 3.31-3.42), and the error
    // between axes i-1 and i joins it (eq. 3.44). The one difference is the linear axes' angular
    // errors, which act about a point travelling with the axis; a thesis matrix placed right of a
    // translation A(q) acts about exactly that point, so those are placed there.
    const Machine m = parse_machine(json::parse(R"({
      "code": "b X Y Z C A t",
      "axes": {"C": {"pivot_mm": [0, 0, 0]}, "A": {"pivot_mm": [0, 0, 0]}},
      "errors": {
        "X": {"EXX_um": 1.0, "EYX_um": -0.7, "EZX_um": 0.4, "EAX_urad": 1.2, "EBX_urad": -0.8, "ECX_urad": 0.5},
        "Y": {"EYY_um": 0.9, "EBY_urad": 0.6, "EC0Y_urad": 1.1},
        "Z": {"EZZ_um": -1.3, "EAZ_urad": 0.7, "EA0Z_urad": -0.9, "EB0Z_urad": 0.4},
        "C": {"EXC_um": 0.8, "EYC_um": -0.5, "EZC_um": 0.3, "EAC_urad": 1.5, "EBC_urad": -1.0, "ECC_urad": 0.9,
              "EX0C_um": 0.6, "EA0C_urad": 0.8},
        "A": {"EXA_um": -0.4, "EYA_um": 0.7, "EZA_um": 0.2, "EAA_urad": -1.1, "EBA_urad": 0.9, "ECA_urad": 1.3,
              "EY0A_um": -0.6, "EZ0A_um": 0.5, "EB0A_urad": -0.7}
      }
    })"));
    using M4 = Eigen::Matrix4d;
    auto trans = [](double x, double y, double z) {
        M4 T = M4::Identity();
        T(0, 3) = x; T(1, 3) = y; T(2, 3) = z;
        return T;
    };
    auto rot = [](int axis, double t) {   // eq. 3.27 with the standard R_y, R_z
        M4 T = M4::Identity();
        const int i = (axis + 1) % 3, j = (axis + 2) % 3;
        T(i, i) = std::cos(t); T(i, j) = -std::sin(t);
        T(j, i) = std::sin(t); T(j, j) = std::cos(t);
        return T;
    };
    auto eps = [](double dx, double dy, double dz, double a, double b, double g) {   // eqs. 3.32 + 3.34
        M4 E = M4::Zero();
        E(0, 1) = -g; E(0, 2) = b; E(1, 0) = g; E(1, 2) = -a; E(2, 0) = -b; E(2, 1) = a;
        E(0, 3) = dx; E(1, 3) = dy; E(2, 3) = dz;
        return E;
    };
    const double um = 1e-3, ur = 1e-6;
    const double X = -420, Y = -310, Z = -150, C = 35, A = -62, L = 140;
    // Motions and their error matrices, from the bed to the tool.
    const M4 AX = trans(X, 0, 0), AY = trans(0, Y, 0), AZ = trans(0, 0, Z);
    const M4 AC = rot(2, C * kDeg), AA = rot(0, A * kDeg);
    const M4 eX_lin = eps(1.0 * um, -0.7 * um, 0.4 * um, 0, 0, 0), eX_ang = eps(0, 0, 0, 1.2 * ur, -0.8 * ur, 0.5 * ur);
    const M4 eY_lin = eps(0, 0.9 * um, 0, 0, 0, 0) + eps(0, 0, 0, 0, 0, 1.1 * ur) /* EC0Y: location, fixed */;
    const M4 eY_ang = eps(0, 0, 0, 0, 0.6 * ur, 0);
    const M4 eZ_lin = eps(0, 0, -1.3 * um, 0, 0, 0) + eps(0, 0, 0, -0.9 * ur, 0.4 * ur, 0);
    const M4 eZ_ang = eps(0, 0, 0, 0.7 * ur, 0, 0);
    const M4 eC = eps(0.8 * um + 0.6 * um, -0.5 * um, 0.3 * um, 1.5 * ur + 0.8 * ur, -1.0 * ur, 0.9 * ur);
    const M4 eA = eps(-0.4 * um, 0.7 * um - 0.6 * um, 0.2 * um + 0.5 * um, -1.1 * ur, 0.9 * ur - 0.7 * ur, 1.3 * ur);
    const M4 T0 = trans(0, 0, -L);
    const M4 nominal = AX * AY * AZ * AC * AA * T0;
    // Eq. 3.43: the nominal product plus one term per error matrix, each inserted in its place.
    const M4 first_order = nominal + eX_lin * nominal + AX * eX_ang * AY * AZ * AC * AA * T0 +
                           AX * eY_lin * AY * AZ * AC * AA * T0 + AX * AY * eY_ang * AZ * AC * AA * T0 +
                           AX * AY * eZ_lin * AZ * AC * AA * T0 + AX * AY * AZ * eZ_ang * AC * AA * T0 +
                           AX * AY * AZ * eC * AC * AA * T0 + AX * AY * AZ * AC * eA * AA * T0;
    const AxisPositions q = positions(m, {{'X', X}, {'Y', Y}, {'Z', Z}, {'C', C}, {'A', A}});
    const ToolPose p = forward(m, q, L);
    const Eigen::Vector3d first_tip = first_order.block<3, 1>(0, 3);
    const Eigen::Vector3d nominal_tip = nominal.block<3, 1>(0, 3);
    // The errors move the tip by about 3 um. Exact and first order differ only by products of two
    // errors: the rotations add up to s_r = 14.4 urad and the translations to s_t = 8.9 um, so the
    // difference is at most s_r^2 R / 2 + s_r s_t = 1.0e-7 + 1.3e-10 mm for lever arms up to
    // R = 1000 mm, and s_r^2 / 2 = 1.0e-10 for the axis (measured: 1.6e-9 mm and 1.1e-11).
    INFO("shift " << (p.tip_mm() - nominal_tip).transpose());
    CHECK((p.tip_mm() - nominal_tip).norm() > 1e-3);
    check_vec(p.tip_mm(), first_tip, 1.3e-7);
    check_vec(p.axis(), first_order.block<3, 1>(0, 2), 1.2e-10);
}
