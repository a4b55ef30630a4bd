// Inverse kinematics: round trips through forward kinematics across the limits of four machines
// (table-table, head-table, an offset head-head, a nutating head), the thesis's closed form for its
// CAYXZ machine (document 000, eqs. 3.13-3.15), the choice among solutions, and unreachable targets.
#include "machine_fixtures.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <random>

using namespace cutload::machine;
using machine_fixtures::kDeg;
using machine_fixtures::kPi;

namespace {

// Rotary axis values drawn across their limits (C tables: one turn and a bit), linear ones inside
// theirs; seeded so a failure can be replayed.
struct Sampler {
    std::mt19937 rng{20240515};
    double uniform(double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng); }
};

// The sine of the angle between the tool axis and the first rotary axis's line (fixed in workpiece
// coordinates: only linear axes can come before it). Near 0 that angle is undetermined (a vertical
// tool on a C table) and only the pose can round-trip.
double singularity(const Machine& m, const AxisPositions& q) {
    for (const Axis& a : m.chain)
        if (a.rotary()) return a.direction.cross(forward(m, q, 0, ErrorMode::Nominal).axis()).norm();
    return 1;
}

void round_trip(const Machine& m, int samples) {
    Sampler s;
    const double L = 125;
    int checked_axes = 0, checked_poses = 0;
    for (int n = 0; n < samples; ++n) {
        AxisPositions q;
        for (std::size_t i = 0; i < m.chain.size(); ++i) {
            const Axis& a = m.chain[i];
            const double lo = std::isfinite(a.lower) ? a.lower : -200;
            const double hi = std::isfinite(a.upper) ? a.upper : 200;
            // Every tenth sample sits exactly on a limit: the round trip must hold there too.
            q.value[i] = n % 10 == 0 ? (n % 20 == 0 ? lo : hi) : s.uniform(lo, hi);
        }
        const ToolPose p = forward(m, q, L, ErrorMode::Nominal);
        // The previous position a controller would come from: near the answer. (Nearer than the
        // other solution: where the two meet, at the edge of a nutating head's reach, they are
        // fractions of a degree apart.)
        AxisPositions prev = q;
        for (std::size_t i = 0; i < m.chain.size(); ++i)
            if (m.chain[i].rotary()) prev.value[i] += s.uniform(-0.05, 0.05);
        const AxisPositions back = inverse(m, p.tip_mm(), p.axis(), L, prev);
        const ToolPose pb = forward(m, back, L, ErrorMode::Nominal);
        INFO(m.name << ", sample " << n);
        CHECK((pb.tip_mm() - p.tip_mm()).norm() < 1e-9);
        CHECK((pb.axis() - p.axis()).norm() < 1e-12);
        ++checked_poses;
        if (singularity(m, q) < 1e-3) continue;   // an angle is nearly free there: the pose is what counts
        for (std::size_t i = 0; i < m.chain.size(); ++i) {
            const double d = back.value[i] - q.value[i];
            INFO("axis " << m.chain[i].name << ": " << q.value[i] << " -> " << back.value[i]);
            CHECK(std::abs(m.chain[i].rotary() ? d * kDeg : d) < 1e-9);   // rad or mm
        }
        ++checked_axes;
    }
    CHECK(checked_axes > samples * 9 / 10);
    CHECK(checked_poses == samples);
}

}  // namespace

TEST_CASE("inverse kinematics: forward then inverse round-trips across the limits", "[machine]") {
    round_trip(machine_fixtures::ac_table_table(), 600);
    round_trip(machine_fixtures::bc_head_table(), 600);
    round_trip(machine_fixtures::ca_head_head(), 600);
    round_trip(machine_fixtures::nutating_head_head(), 600);
}

TEST_CASE("inverse kinematics agrees with the thesis's closed form for its CAYXZ machine (eqs. 3.13-3.15)", "[machine]") {
    // The thesis machine (see the forward test): C, A through the origin, sense -1. Its closed form:
    //   A = arccos k,  C = sgn(i) arccos(j / sqrt(i^2 + j^2)) with sgn(i) = -1 for i < 0 (the printed
    //   0 is a misprint), (X, Y, Z) = M(A, C)^-1 r_trj.
    const Machine m = parse_machine(nlohmann::json::parse(R"({
      "code": "C A b Y X Z t",
      "axes": {"C": {"pivot_mm": [0, 0, 0], "sense": -1}, "A": {"pivot_mm": [0, 0, 0], "sense": -1, "limits_deg": [0, 180]}}
    })"));
    Sampler s;
    for (int n = 0; n < 200; ++n) {
        const double theta = s.uniform(0.05, kPi - 0.05), phi = s.uniform(-kPi, kPi);
        const Eigen::Vector3d ijk(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta));
        const Eigen::Vector3d r_trj(s.uniform(-100, 100), s.uniform(-100, 100), s.uniform(-100, 100));
        const double i = ijk.x(), j = ijk.y(), k = ijk.z();
        const double A = std::acos(k);
        const double C = (i >= 0 ? 1 : -1) * std::acos(j / std::sqrt(i * i + j * j));
        Eigen::Matrix3d M;
        M << std::cos(C), std::cos(A) * std::sin(C), std::sin(A) * std::sin(C),
            -std::sin(C), std::cos(A) * std::cos(C), std::cos(C) * std::sin(A),
            0, -std::sin(A), std::cos(A);
        const Eigen::Vector3d xyz = M.inverse() * r_trj;
        AxisPositions prev = positions(m, {{'A', A / kDeg + 1}, {'C', C / kDeg - 1}});
        const AxisPositions q = inverse(m, r_trj, ijk, 0, prev);
        INFO("i, j, k = " << ijk.transpose());
        CHECK(std::abs(q.value[m.index_of('A')] * kDeg - A) < 1e-9);
        CHECK(std::abs(q.value[m.index_of('C')] * kDeg - C) < 1e-9);
        CHECK(std::abs(q.value[m.index_of('X')] - xyz.x()) < 1e-9);
        CHECK(std::abs(q.value[m.index_of('Y')] - xyz.y()) < 1e-9);
        CHECK(std::abs(q.value[m.index_of('Z')] - xyz.z()) < 1e-9);
    }
}

TEST_CASE("inverse kinematics picks the solution nearest the previous position within limits", "[machine]") {
    const Machine m = machine_fixtures::ac_table_table();
    const double L = 100;
    const std::size_t iA = m.index_of('A'), iC = m.index_of('C');
    // Tool axis (0, -sin 60, cos 60): A = +60 with C = 0, or A = -60 with C = 180 (check:
    // R_z(180) R_x(-60) e_z = R_z(180) (0, sin 60, cos 60) = (0, -sin 60, cos 60)). A is limited to
    // [-120, 30], so only the second fits, however near the first the previous position is.
    const Eigen::Vector3d axis(0, -std::sin(60 * kDeg), std::cos(60 * kDeg));
    const Eigen::Vector3d tip(-300, -200, -450);
    AxisPositions q = inverse(m, tip, axis, L, positions(m, {{'A', 25}, {'C', 5}}));
    CHECK(q.value[iA] == Approx(-60).margin(1e-9));
    CHECK(q.value[iC] == Approx(180).margin(1e-9));
    // A continuous C takes the equivalent nearest the previous value: from C = -170 it goes to
    // -180, not +180; from C = 530 to 540.
    q = inverse(m, tip, axis, L, positions(m, {{'A', -50}, {'C', -170}}));
    CHECK(q.value[iC] == Approx(-180).margin(1e-9));
    q = inverse(m, tip, axis, L, positions(m, {{'A', -50}, {'C', 530}}));
    CHECK(q.value[iC] == Approx(540).margin(1e-9));
    // A vertical tool leaves C free: it stays where it was.
    q = inverse(m, tip, Eigen::Vector3d::UnitZ(), L, positions(m, {{'A', -3}, {'C', 47.25}}));
    CHECK(q.value[iA] == Approx(0).margin(1e-9));
    CHECK(q.value[iC] == 47.25);
    CHECK((forward(m, q, L).tip_mm() - tip).norm() < 1e-9);
    // Tilted, both branches within limits: A = -20 (C near 0) or A = +20 (C near 180). From near
    // the first the first, from near the second the second.
    const Eigen::Vector3d tilt(0, std::sin(20 * kDeg), std::cos(20 * kDeg));
    q = inverse(m, tip, tilt, L, positions(m, {{'A', -15}, {'C', 10}}));
    CHECK(q.value[iA] == Approx(-20).margin(1e-9));
    CHECK(q.value[iC] == Approx(0).margin(1e-9));
    q = inverse(m, tip, tilt, L, positions(m, {{'A', 15}, {'C', 170}}));
    CHECK(q.value[iA] == Approx(20).margin(1e-9));
    CHECK(q.value[iC] == Approx(180).margin(1e-9));
}

TEST_CASE("inverse kinematics refuses targets outside the machine's reach, naming the axis", "[machine]") {
    const Machine ac = machine_fixtures::ac_table_table();
    const AxisPositions home;
    // A tool pointing straight up from below the part needs A = +-180: outside [-120, 30].
    CHECK_THROWS_WITH(inverse(ac, Eigen::Vector3d(-300, -200, -450), -Eigen::Vector3d::UnitZ(), 100, home),
                      Catch::Matchers::Contains("axis A would need"));
    // A tip beyond X travel.
    CHECK_THROWS_WITH(inverse(ac, Eigen::Vector3d(250, -200, -450), Eigen::Vector3d::UnitZ(), 100, home),
                      Catch::Matchers::Contains("axis X would need 250.000000 mm, outside its limits [-700, 0]"));
    // The nutating head reaches no further than 90 deg from vertical.
    const Machine nut = machine_fixtures::nutating_head_head();
    CHECK_THROWS_WITH(inverse(nut, Eigen::Vector3d(-300, -200, -300), Eigen::Vector3d(0, 0.6, -0.8), 100,
                              AxisPositions{}),
                      Catch::Matchers::Contains("out of reach of rotary axes C and B"));
    CHECK_THROWS_AS(inverse(ac, Eigen::Vector3d(-300, -200, -450), Eigen::Vector3d::Zero(), 100, home),
                    KinematicsError);
}
