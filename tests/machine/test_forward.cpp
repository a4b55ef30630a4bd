// Forward kinematics against poses worked out by hand (rotations written out as the few products
// they are), the thesis's CAYXZ transform (document 000, eq. 3.15), and the table-rotation
// invariance the engine's later tests build on.
#include "machine_fixtures.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <random>

using namespace cutload::machine;
using machine_fixtures::kDeg;

namespace {

void check_vec(const Eigen::Vector3d& got, const Eigen::Vector3d& want, double tol) {
    INFO("got (" << got.transpose() << "), want (" << want.transpose() << ")");
    CHECK((got - want).norm() < tol);
}

}  // namespace

TEST_CASE("BC head-table: B at 90 deg swings the tip about the head pivot, 230 mm above the gauge point", "[machine]") {
    const Machine m = machine_fixtures::bc_head_table();
    const double L = 100;
    // B pivot 230 mm above the gauge point; the tip 330 mm below the pivot swings onto -X:
    // R_y(90) (0, 0, -330) = (-330, 0, 0), so tip = (X, Y, Z) + (0, 0, 230) + (-330, 0, 0).
    const ToolPose p = forward(m, positions(m, {{'X', -500}, {'Y', -300}, {'Z', -200}, {'B', 90}}), L);
    check_vec(p.tip_mm(), Eigen::Vector3d(-830, -300, 30), 1e-12);
    check_vec(p.axis(), Eigen::Vector3d(1, 0, 0), 1e-15);                              // R_y(90) z
    check_vec(p.tool_to_workpiece.R.col(0), Eigen::Vector3d(0, 0, -1), 1e-15);          // R_y(90) x
    // At B = 0 the tool hangs straight down from the gauge point.
    const ToolPose h = forward(m, positions(m, {{'X', -500}, {'Y', -300}, {'Z', -200}}), L);
    check_vec(h.tip_mm(), Eigen::Vector3d(-500, -300, -300), 1e-12);
    check_vec(h.axis(), Eigen::Vector3d(0, 0, 1), 1e-15);
}

TEST_CASE("AC table-table: A at -90 deg and C at 90 deg turn the tool about the trunnion and table lines", "[machine]") {
    const Machine m = machine_fixtures::ac_table_table();
    const double L = 120;
    // A line through (-350, -275, -560) along X. w = (X, Y, Z - L) = (-350, -275, -220);
    // w - pA = (0, 0, 340); R_x(-90) (x, y, z) = (x, z, -y) gives (0, 340, 0): tip (-350, 65, -560).
    const ToolPose a = forward(m, positions(m, {{'X', -350}, {'Y', -275}, {'Z', -100}, {'A', -90}}), L);
    check_vec(a.tip_mm(), Eigen::Vector3d(-350, 65, -560), 1e-12);
    check_vec(a.axis(), Eigen::Vector3d(0, 1, 0), 1e-15);
    // C = 90 about the line through (-350, -275) along Z: R_z(90) (x, y, z) = (-y, x, z) turns
    // tip - pC = (0, 340, 0) into (-340, 0, 0), and the axis (0, 1, 0) into (-1, 0, 0).
    const ToolPose c = forward(m, positions(m, {{'X', -350}, {'Y', -275}, {'Z', -100}, {'A', -90}, {'C', 90}}), L);
    check_vec(c.tip_mm(), Eigen::Vector3d(-690, -275, -560), 1e-12);
    check_vec(c.axis(), Eigen::Vector3d(-1, 0, 0), 1e-15);
}

TEST_CASE("AC table-table: C turned 90 deg maps a straight move to the same move turned about the C line", "[machine]") {
    // The basis of the later invariance test: a part clamped on the C table and cut with C at 0
    // or at 90 deg sees the same tool motion, only turned with the table.
    const Machine m = machine_fixtures::ac_table_table();
    const Eigen::Vector3d pC = m.chain[m.index_of('C')].pivot_mm;
    const double L = 95;
    for (const double A : {0.0, -30.0, -90.0, 20.0}) {
        for (int k = 0; k <= 10; ++k) {
            const double s = k / 10.0;
            // A straight move in X, Y and Z together.
            const std::map<char, double> q = {{'X', -400 + 100 * s}, {'Y', -200 - 40 * s}, {'Z', -150 + 25 * s}, {'A', A}};
            auto q90 = q;
            q90['C'] = 90;
            const ToolPose p0 = forward(m, positions(m, q), L);
            const ToolPose p90 = forward(m, positions(m, q90), L);
            const Eigen::Vector3d d = p0.tip_mm() - pC;
            INFO("A = " << A << ", s = " << s);
            check_vec(p90.tip_mm(), pC + Eigen::Vector3d(-d.y(), d.x(), d.z()), 1e-10);   // R_z(90) by hand
            const Eigen::Vector3d a0 = p0.axis();
            check_vec(p90.axis(), Eigen::Vector3d(-a0.y(), a0.x(), a0.z()), 1e-14);
            if (k == 0 || k == 10) continue;
            // Still straight: every point on the chord between the ends.
            const ToolPose e0 = forward(m, positions(m, {{'X', -400}, {'Y', -200}, {'Z', -150}, {'A', A}, {'C', 90}}), L);
            const ToolPose e1 = forward(m, positions(m, {{'X', -300}, {'Y', -240}, {'Z', -125}, {'A', A}, {'C', 90}}), L);
            check_vec(p90.tip_mm(), e0.tip_mm() + s * (e1.tip_mm() - e0.tip_mm()), 1e-10);
        }
    }
}

TEST_CASE("the thesis's CAYXZ machine (eq. 3.15) is the code C A b Y X Z with both rotary senses reversed", "[machine]") {
    // Document 000, eq. 3.15: r_trj = M (X, Y, Z) and r_pst = M e_z with
    //   M = [[cos C, cos A sin C, sin A sin C], [-sin C, cos A cos C, cos C sin A], [0, -sin A, cos A]],
    // rotary axes through the workpiece origin, no tool length. M = R_z(-C) R_x(-A): the thesis
    // turns the table by +C, so the tool turns by -C relative to it, which is sense -1 here.
    const Machine m = parse_machine(nlohmann::json::parse(R"({
      "code": "C A b Y X Z t",
      "axes": {"C": {"pivot_mm": [0, 0, 0], "sense": -1}, "A": {"pivot_mm": [0, 0, 0], "sense": -1}}
    })"));
    for (const double A : {0.0, 15.0, 40.0, 120.0, 170.0})
        for (const double C : {-150.0, -30.0, 0.0, 65.0, 180.0}) {
            const double a = A * kDeg, c = C * kDeg;
            Eigen::Matrix3d M;
            M << std::cos(c), std::cos(a) * std::sin(c), std::sin(a) * std::sin(c),
                -std::sin(c), std::cos(a) * std::cos(c), std::cos(c) * std::sin(a),
                0, -std::sin(a), std::cos(a);
            const Eigen::Vector3d xyz(37.5, -12.25, 80);
            const ToolPose p = forward(m, positions(m, {{'X', xyz.x()}, {'Y', xyz.y()}, {'Z', xyz.z()}, {'A', A}, {'C', C}}), 0);
            INFO("A = " << A << ", C = " << C);
            check_vec(p.tip_mm(), M * xyz, 1e-12);
            check_vec(p.axis(), M.col(2), 1e-15);
        }
}

TEST_CASE("the bed frame turns machine axes into workpiece axes", "[machine]") {
    // On a table-table machine the tool always points along the machine's Z: its axis in
    // workpiece coordinates is the bed frame's Z. On the head-table machine only the table turns
    // the bed, so the axis is R_bed (R_y(B) e_z).
    const Machine ac = machine_fixtures::ac_table_table();
    for (const double A : {-110.0, -45.0, 25.0})
        for (const double C : {0.0, 33.0, 250.0}) {
            const AxisPositions q = positions(ac, {{'X', -100}, {'Y', -50}, {'Z', -20}, {'A', A}, {'C', C}});
            check_vec(bed_to_workpiece(ac, q).R.col(2), forward(ac, q, 100).axis(), 1e-14);
        }
    const Machine bc = machine_fixtures::bc_head_table();
    const double B = 35, C = 120;
    const AxisPositions q = positions(bc, {{'X', -100}, {'Y', -50}, {'Z', -20}, {'B', B}, {'C', C}});
    const Eigen::Vector3d axis_in_bed(std::sin(B * kDeg), 0, std::cos(B * kDeg));
    check_vec(bed_to_workpiece(bc, q).R * axis_in_bed, forward(bc, q, 100).axis(), 1e-14);
    // The bed frame at C = 120: the C line is its fixed point, and machine X turns to (cos, sin, 0).
    const Frame bed = bed_to_workpiece(bc, q);
    check_vec(bed.R.col(0), Eigen::Vector3d(std::cos(C * kDeg), std::sin(C * kDeg), 0), 1e-15);
    const Eigen::Vector3d pC = bc.chain[0].pivot_mm;
    check_vec(apply(bed, pC), pC, 1e-12);
}

TEST_CASE("forward_with_bed equals forward and bed_to_workpiece, bit for bit, with and without errors", "[machine]") {
    Machine ac = machine_fixtures::ac_table_table();
    Machine ac_errors = ac;
    load_errors(ac_errors, machine_fixtures::data_path("ac_table_table_errors.json"));
    // No error set is bundled for BC; one of the same kinds (location, constant and tabulated
    // component errors on a linear, the table and the head axis), so both halves of its chain carry errors.
    Machine bc = machine_fixtures::bc_head_table();
    Machine bc_errors = bc;
    set_errors(bc_errors, nlohmann::json::parse(R"({
      "X": {"EXX_um": {"at_mm": [-1200, -600, 0], "values": [7.5, 3.0, 0]}, "EC0X_urad": -9},
      "C": {"EX0C_um": -5, "EY0C_um": 11, "EA0C_urad": 8, "EB0C_urad": 14,
            "ECC_arcsec": {"at_deg": [0, 90, 180, 270, 360], "values": [0, 2.0, -1.5, -2.5, 0]}},
      "B": {"EX0B_um": 9, "EZ0B_um": -6, "EA0B_urad": -12, "EC0B_urad": 7,
            "EBB_arcsec": {"at_deg": [-110, 0, 110], "values": [-4, 0, 3]}}
    })"));
    std::mt19937 rng(2026);
    for (const Machine* m : {&ac, &ac_errors, &bc, &bc_errors}) {
        INFO(m->name << (m == &ac_errors || m == &bc_errors ? ", with errors" : ""));
        std::size_t differ = 0;
        for (int n = 0; n < 2000; ++n) {
            AxisPositions q;
            for (std::size_t i = 0; i < m->chain.size(); ++i) {
                const Axis& a = m->chain[i];
                // A continuous axis over a few turns; otherwise its travel.
                const double lo = std::isfinite(a.lower) ? a.lower : -720, hi = std::isfinite(a.upper) ? a.upper : 720;
                q.value[i] = std::uniform_real_distribution<double>(lo, hi)(rng);
            }
            for (const ErrorMode mode : {ErrorMode::Nominal, ErrorMode::WithErrors}) {
                const double length_mm = n % 3 == 0 ? 0.0 : 85.5;
                const ToolAndBed both = forward_with_bed(*m, q, length_mm, mode);
                const ToolPose tool = forward(*m, q, length_mm, mode);
                const Frame bed = bed_to_workpiece(*m, q, mode);
                differ += both.tool.tool_to_workpiece.R != tool.tool_to_workpiece.R ||
                          both.tool.tip_mm() != tool.tip_mm() || both.bed_to_workpiece.R != bed.R ||
                          both.bed_to_workpiece.origin_mm != bed.origin_mm;
            }
        }
        CHECK(differ == 0);
    }
}
