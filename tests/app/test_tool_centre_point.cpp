// NC programs under tool-centre-point control (G43.4/G43.5; docs/five_axis.md section 2.4) turned
// into machine-axis form on the bundled AC table-table machine (app/tool_centre_point.hpp). The
// references are closed forms written here, not the code under test:
// - document 000's section 1.3 path (docs/five_axis.md section 8): on the branch A = -theta,
//   C = 180 deg the machine runs X = -350, Y = -275 - 10 t, Z = -460 + 20 t, A = -40 t deg, and
//   the tip is r_trj(t), the tool axis r_pst(t);
// - a C turn with the tip held 100 mm off the C line: the tip stays put, the spindle runs on the
//   circle of 100 mm about the C line.
#include "app/tool_centre_point.hpp"
#include "app/workpiece_motion.hpp"
#include "app_fixtures.hpp"
#include "machine/kinematics.hpp"
#include "motion_io/commanded.hpp"

#include <catch2/catch.hpp>
#include <fmt/format.h>

#include <cmath>
#include <numbers>
#include <string>

using namespace cutload;
using motion_io::NcBlock;
using motion_io::NcProgram;

namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kL = 120;                  // tool length, mm
const Eigen::Vector3d kOrigin(-350, -275, -560);   // the rotary axes' intersection (section 8)

double theta(double t) { return 2 * kPi * t / 9; }
Eigen::Vector3d r_trj(double t) {
    const double c = std::cos(theta(t)), s = std::sin(theta(t));
    return kOrigin + Eigen::Vector3d(0, 10 * t * c + (20 - 20 * t) * s, (20 * t - 20) * c + 10 * t * s);
}
Eigen::Vector3d r_pst(double t) { return {0, -std::sin(theta(t)), std::cos(theta(t))}; }

std::shared_ptr<const machine::Machine> ac_machine() {
    static const auto m = app::load_machine_definition(apptest::source_path("data/machines/ac_table_table.json"));
    return m;
}

// G54 at the workpiece origin (the tip's words are workpiece coordinates); the machine starts at
// the path's start, t = 0: A = 0, C = 180 deg, the tip at r_trj(0).
motion_io::NcReadOptions tcp_options(bool with_kinematics = true) {
    motion_io::NcReadOptions o;
    o.work_offsets_mm["G54"] = {0, 0, 0};
    o.start_mm = std::array<double, 3>{-350, -275, -460};
    o.start_deg = {0, 0, 180};
    o.rotary_axes = "AC";
    if (with_kinematics) o.tool_centre_point = app::tool_centre_point_kinematics(ac_machine(), kL);
    return o;
}

NcProgram read(const std::string& text, const motion_io::NcReadOptions& o = tcp_options()) {
    const NcProgram p = motion_io::parse_nc_program(text, "t.nc", o);
    return app::machine_axis_program(p, *o.tool_centre_point);
}

std::string error_of(const std::string& text, const motion_io::NcReadOptions& o = tcp_options()) {
    try {
        if (o.tool_centre_point) read(text, o);
        else motion_io::parse_nc_program(text, "t.nc", o);
    } catch (const motion_io::NcProgramError& e) {
        return e.what();
    }
    return "(no error)";
}

// Section 8's path as `blocks` G93 blocks of equal time over t in [0, 1] s: tip r_trj(t_k) and
// the orientation as A/C words (G43.4), as I/J/K = r_pst(t_k) (G43.5), or the closed-form machine
// axes (machine-axis form, no tool-centre-point control).
enum class Form { RotaryAngles, AxisVector, MachineAxes };
std::string doc000_program(Form form, int blocks) {
    std::string text;
    if (form == Form::RotaryAngles) text += "N10 G43.4 H1\n";
    if (form == Form::AxisVector) text += "N10 G43.5 H1\n";
    const double f_per_min = 60.0 * blocks;   // each block takes 1/blocks s
    for (int k = 1; k <= blocks; ++k) {
        const double t = double(k) / blocks;
        const Eigen::Vector3d tip = r_trj(t), axis = r_pst(t);
        const std::string head = fmt::format("N{} {}G01 ", 20 + k, k == 1 ? "G93 " : "");
        if (form == Form::RotaryAngles)
            text += head + fmt::format("X{:.9f} Y{:.9f} Z{:.9f} A{:.9f} C180. F{:.3f}\n", tip.x(), tip.y(), tip.z(), -40 * t, f_per_min);
        else if (form == Form::AxisVector)
            text += head + fmt::format("X{:.9f} Y{:.9f} Z{:.9f} I0 J{:.12f} K{:.12f} F{:.3f}\n", tip.x(), tip.y(), tip.z(), axis.y(),
                                       axis.z(), f_per_min);
        else
            text += head + fmt::format("X-350. Y{:.9f} Z{:.9f} A{:.9f} C180. F{:.3f}\n", -275 - 10 * t, -460 + 20 * t, -40 * t, f_per_min);
    }
    if (form != Form::MachineAxes) text += "N900 G49\n";
    return text;
}

// The machine's axes at program time t_s: every axis linear within a piece (joint space), each
// piece taking its feed_time_s.
machine::AxisPositions axes_at(const NcProgram& p, double t_s) {
    double begin_s = 0;
    const NcBlock* last = nullptr;
    for (const NcBlock& b : p.blocks) {
        if (!motion_io::block_moves(b)) continue;
        const double d = motion_io::block_time_s(b, 30000);
        last = &b;
        if (t_s <= begin_s + d) {
            const double u = std::clamp((t_s - begin_s) / d, 0.0, 1.0);
            return machine::positions(*ac_machine(), {{'X', b.start_mm[0] + u * (b.end_mm[0] - b.start_mm[0])},
                                                      {'Y', b.start_mm[1] + u * (b.end_mm[1] - b.start_mm[1])},
                                                      {'Z', b.start_mm[2] + u * (b.end_mm[2] - b.start_mm[2])},
                                                      {'A', b.start_deg[0] + u * (b.end_deg[0] - b.start_deg[0])},
                                                      {'C', b.start_deg[2] + u * (b.end_deg[2] - b.start_deg[2])}});
        }
        begin_s += d;
    }
    REQUIRE(last);
    return machine::positions(*ac_machine(), {{'X', last->end_mm[0]}, {'Y', last->end_mm[1]}, {'Z', last->end_mm[2]},
                                              {'A', last->end_deg[0]}, {'C', last->end_deg[2]}});
}

double program_s(const NcProgram& p) {
    double s = 0;
    for (const NcBlock& b : p.blocks) s += motion_io::block_moves(b) ? motion_io::block_time_s(b, 30000) : 0.0;
    return s;
}

}  // namespace

TEST_CASE("tool-centre-point: a G43.4 program of the doc000 path puts the tip on r_trj(t) within 1 um", "[tcp][doc000]") {
    const NcProgram p = read(doc000_program(Form::RotaryAngles, 200));
    CHECK(p.rotary_axes == "ac");
    CHECK_FALSE(app::has_tool_centre_point(p));
    CHECK(program_s(p) == Approx(1.0).epsilon(1e-12));
    // Block ends: the closed-form axes of the A = -theta, C = 180 deg branch.
    double worst_axes = 0;
    for (const NcBlock& b : p.blocks) {
        if (!motion_io::block_moves(b)) continue;
        const double t = -b.end_deg[0] / 40;
        worst_axes = std::max({worst_axes, std::abs(b.end_mm[0] + 350), std::abs(b.end_mm[1] - (-275 - 10 * t)),
                               std::abs(b.end_mm[2] - (-460 + 20 * t)), std::abs(b.end_deg[2] - 180)});
    }
    CHECK(worst_axes < 1e-9);
    // Between them the program's tip runs on the chords of r_trj, which sag from it by at most
    // |r''| dt^2 / 8 = 0.13 um (|r''| <= 41 mm/s^2, dt = 5 ms blocks). Joint-space interpolation
    // of the block ends stays on r_trj itself (every axis is linear in t on this branch), within
    // the 1 um of the chords: no block needs bisection. The tool axis stays on r_pst.
    double worst_tip_mm = 0, worst_chord_mm = 0, worst_axis = 0;
    for (int i = 0; i <= 1000; ++i) {
        const double t = i / 1000.0;
        const machine::ToolPose pose = machine::forward(*ac_machine(), axes_at(p, t), kL, machine::ErrorMode::Nominal);
        const double k = std::min(std::floor(t * 200), 199.0), u = t * 200 - k;
        const Eigen::Vector3d chord = r_trj(k / 200) + u * (r_trj((k + 1) / 200) - r_trj(k / 200));
        worst_tip_mm = std::max(worst_tip_mm, (pose.tip_mm() - r_trj(t)).norm());
        worst_chord_mm = std::max(worst_chord_mm, (pose.tip_mm() - chord).norm());
        worst_axis = std::max(worst_axis, (pose.axis() - r_pst(t)).norm());
    }
    WARN(fmt::format("G43.4 doc000 path, 200 blocks: {} blocks out, tip within {:.3g} um of r_trj and {:.3g} um of the programmed "
                     "chords, axis within {:.3g} of r_pst",
                     p.blocks.size(), worst_tip_mm * 1e3, worst_chord_mm * 1e3, worst_axis));
    CHECK(p.blocks.size() == 202);   // G43.4, 200 moves, G49
    CHECK(worst_tip_mm < 1e-3);
    CHECK(worst_chord_mm < app::kTcpTipTolMm);
    CHECK(worst_axis < 1e-9);
}

TEST_CASE("tool-centre-point: a G43.5 program with I/J/K = r_pst(t) gives the axes of its G43.4 twin", "[tcp][doc000]") {
    const NcProgram angles = read(doc000_program(Form::RotaryAngles, 200));
    const NcProgram vector = read(doc000_program(Form::AxisVector, 200));
    // The great circle between r_pst(t_k) and r_pst(t_k+1) is the turn about X, as A linear is.
    double worst = 0;
    for (int i = 0; i <= 2000; ++i) {
        const double t = i / 2000.0;
        const machine::AxisPositions a = axes_at(angles, t), v = axes_at(vector, t);
        for (std::size_t k = 0; k < ac_machine()->chain.size(); ++k) worst = std::max(worst, std::abs(a.value[k] - v.value[k]));
    }
    WARN(fmt::format("G43.5 against G43.4, doc000 path: axes agree within {:.3g} (mm, deg)", worst));
    CHECK(worst < 1e-6);
    CHECK(program_s(vector) == Approx(1.0).epsilon(1e-12));
}

TEST_CASE("tool-centre-point: a G43.4 program runs as its machine-axis twin, through the commanded motion too", "[tcp][doc000]") {
    const NcProgram tcp = read(doc000_program(Form::RotaryAngles, 200));
    const NcProgram twin = read(doc000_program(Form::MachineAxes, 200));
    double worst_mm = 0, worst_deg = 0;
    for (int i = 0; i <= 2000; ++i) {
        const double t = i / 2000.0;
        const machine::AxisPositions a = axes_at(tcp, t), b = axes_at(twin, t);
        for (std::size_t k = 0; k < ac_machine()->chain.size(); ++k) {
            const double d = std::abs(a.value[k] - b.value[k]);
            if (ac_machine()->chain[k].rotary()) worst_deg = std::max(worst_deg, d);
            else worst_mm = std::max(worst_mm, d);
        }
    }
    CHECK(worst_mm < 1e-3);
    CHECK(worst_deg < 1e-9);
    // Downstream of the reader nothing tells the two apart: the commanded motion of both.
    motion_io::CommandedOptions co;
    const motion_io::MotionModel m1 = motion_io::commanded_motion(tcp, co), m2 = motion_io::commanded_motion(twin, co);
    REQUIRE(m1.size() == m2.size());
    REQUIRE(m1.has_rotary(0));
    double worst_motion = 0;
    for (std::size_t i = 0; i < m1.size(); ++i)
        worst_motion = std::max({worst_motion, std::abs(m1.x_mm[i] - m2.x_mm[i]), std::abs(m1.y_mm[i] - m2.y_mm[i]),
                                 std::abs(m1.z_mm[i] - m2.z_mm[i]), std::abs(m1.rot_deg[0][i] - m2.rot_deg[0][i]),
                                 std::abs(m1.rot_deg[2][i] - m2.rot_deg[2][i])});
    WARN(fmt::format("G43.4 against its machine-axis twin: axes within {:.3g} mm and {:.3g} deg, commanded motion within {:.3g}",
                     worst_mm, worst_deg, worst_motion));
    CHECK(worst_motion < 1e-3);
}

TEST_CASE("tool-centre-point: a C turn with the tip held 100 mm off the C line is bisected to 1 um", "[tcp]") {
    // Start: A = 0, C = 180 deg, the spindle 100 mm off the C line in X; the tip stays where it is
    // while C turns 90 deg, so the machine's X and Y run a quarter circle of 100 mm about the C line.
    motion_io::NcReadOptions o = tcp_options();
    o.start_mm = std::array<double, 3>{-250, -275, -460};
    const NcProgram p = read("N10 G43.4 H1\nN20 G94 G01 C270. F3600\nN30 G49\n", o);
    const machine::ToolPose start = machine::forward(*ac_machine(), machine::positions(*ac_machine(), {{'X', -250}, {'Y', -275}, {'Z', -460}, {'C', 180}}), kL,
                                                     machine::ErrorMode::Nominal);
    std::size_t pieces = 0;
    double worst_radius = 0;
    for (const NcBlock& b : p.blocks) {
        if (b.name != "N20") continue;
        ++pieces;
        worst_radius = std::max(worst_radius, std::abs(std::hypot(b.end_mm[0] + 350, b.end_mm[1] + 275) - 100));
        CHECK(b.end_mm[2] == Approx(-460).margin(1e-9));
    }
    // A pure turn at F3600 reads F as deg/min: 90 deg take 1.5 s.
    CHECK(program_s(p) == Approx(1.5).epsilon(1e-12));
    double worst_tip_mm = 0;
    for (int i = 0; i <= 3000; ++i) {
        const machine::ToolPose pose = machine::forward(*ac_machine(), axes_at(p, 1.5 * i / 3000.0), kL, machine::ErrorMode::Nominal);
        worst_tip_mm = std::max(worst_tip_mm, (pose.tip_mm() - start.tip_mm()).norm());
    }
    WARN(fmt::format("C turn of 90 deg, tip 100 mm off the C line: {} pieces, tip within {:.3g} um", pieces, worst_tip_mm * 1e3));
    CHECK(worst_radius < 1e-9);
    CHECK(worst_tip_mm <= app::kTcpTipTolMm);
    // A chord of angle phi on the 100 mm circle strays 100 (1 - cos(phi / 2)) from it: 1 um
    // needs phi <= 0.51 deg, so 90 deg take at least 176 pieces (bisection makes a power of two).
    CHECK(pieces >= 176);
    CHECK(pieces <= 512);
}

TEST_CASE("tool-centre-point: an unreachable orientation is refused naming file, line, block, axis and limits", "[tcp][errors]") {
    // A on the bundled machine turns within [-120, 30] deg.
    CHECK_THAT(error_of("N10 G43.4 H1\nN20 G01 X-350. Y-275. Z-580. A-150. C180. F600\n"),
               Catch::StartsWith("t.nc:2: word 'X-350.': block N20: the machine cannot reach the tip (-350, -275, -580) at the rotary "
                                 "angles (-150, 0, 180): axis A at -150 deg is outside its limits [-120, 30]"));
    // A tool axis 150 deg from the table's +Z needs A = +-150 deg on either branch.
    const std::string down = error_of("N10 G43.5 H1\nN20 G01 X-350. Y-275. Z-580. I0 J0.5 K-0.8660254 F600\n");
    CHECK_THAT(down, Catch::StartsWith("t.nc:2: word 'X-350.': block N20: the machine cannot reach the tip (-350, -275, -580) with the "
                                       "tool axis (0, 0.5, -0.866025)"));
    CHECK_THAT(down, Catch::Contains("axis A would need") && Catch::EndsWith("outside its limits [-120, 30]"));
    // A tip beyond the linear travel names that axis.
    CHECK_THAT(error_of("N10 G43.4 H1\nN20 G01 Z200. F600\n"), Catch::Contains("block N20") && Catch::Contains("axis Z would need"));
    // Without the machine's kinematics there is no tool-centre-point program.
    CHECK_THAT(error_of("N10 G43.4 H1\n", tcp_options(false)),
               Catch::StartsWith("t.nc:1: word 'G43.4': tool-centre-point control (G43.4) needs the machine's kinematics"));
    // The tool axis turning to its opposite has no great circle.
    CHECK_THAT(error_of("N10 G43.5 H1\nN20 G01 I0 J0 K-1. F600\n"), Catch::Contains("no great circle"));
    CHECK_THAT(error_of("N10 G43.4 H1\nN20 G02 X-340. F600\n"), Catch::Contains("circular interpolation under tool-centre-point control"));
    CHECK_THAT(error_of("N10 G43.5 H1\nN20 G01 X-340. A10. F600\n"), Catch::Contains("a rotary word under G43.5"));
}

TEST_CASE("tool-centre-point: G49 cancels, and later blocks are machine-axis moves from where the machine is", "[tcp]") {
    // N20 moves the tip 10 mm in +Y of the workpiece with A = -30 deg, C = 180 deg; the machine
    // then stands at Y = -275 - 10 cos 30 deg ... by the closed form below.
    const NcProgram p = read("N10 G43.4 H1\n"
                             "N20 G01 X-350. Y-265. Z-580. A-30. C180. F600\n"
                             "N30 G49\n"
                             "N40 G01 X-340. F600\n"
                             "N50 G91 Y5.\n"
                             "N60 G90 G43.5\n"
                             "N70 G01 Z-570.\n");
    // The table's turns take the machine frame to the workpiece's: p_W - pivot = R_z(C) R_x(A)
    // (p_M - pivot) (ISO 841 senses: A = -30 deg turns the tool -30 deg about X against the part).
    // So the tip (0, 10, -20) from the pivot in workpiece axes is R_x(30) R_z(-180) of it in machine
    // axes, and the spindle's gauge point 120 mm above that (the tool stays along machine +Z).
    const double c30 = std::cos(kPi / 6), s30 = std::sin(kPi / 6);
    const double y_m = -10 * c30 + 20 * s30, z_m = -10 * s30 - 20 * c30;
    const NcBlock* n20 = nullptr;
    for (const NcBlock& b : p.blocks)
        if (b.name == "N20") n20 = &b;
    REQUIRE(n20);
    CHECK(n20->end_mm[0] == Approx(-350).margin(1e-9));
    CHECK(n20->end_mm[1] == Approx(-275 + y_m).margin(1e-9));
    CHECK(n20->end_mm[2] == Approx(-560 + z_m + kL).margin(1e-9));
    const auto named = [&](const std::string& name) -> const NcBlock& {
        for (const NcBlock& b : p.blocks)
            if (b.name == name) return b;
        FAIL("no block " << name);
        return p.blocks.front();
    };
    const NcBlock& n40 = named("N40");
    CHECK(n40.tcp == motion_io::ToolCentrePoint::Off);
    CHECK(n40.start_mm == n20->end_mm);
    CHECK(n40.end_mm[0] == -340);
    CHECK(n40.end_mm[1] == n20->end_mm[1]);
    CHECK(n40.start_deg == std::array<double, 3>{-30, 0, 180});
    CHECK(n40.end_deg == n40.start_deg);
    CHECK(n40.feed_time_s == 0);   // a three-axis line at F: 10 mm over 600 mm/min
    CHECK(motion_io::block_time_s(n40, 30000) == Approx(1.0).epsilon(1e-12));
    const NcBlock& n50 = named("N50");
    CHECK(n50.end_mm[1] == Approx(n20->end_mm[1] + 5).margin(1e-12));   // incremental from the machine's Y
    // Back under control (G43.5): the tip starts where the machine put it, and Z-570 moves it to
    // that height in the workpiece's Z, along which the tool leans 30 deg: the machine's Y and Z
    // share the move.
    const NcBlock& n70 = named("N70");
    CHECK(n70.start_mm == n50.end_mm);
    const machine::ToolPose end = machine::forward(*ac_machine(),
                                                   machine::positions(*ac_machine(), {{'X', n70.end_mm[0]}, {'Y', n70.end_mm[1]},
                                                                                      {'Z', n70.end_mm[2]}, {'A', n70.end_deg[0]},
                                                                                      {'C', n70.end_deg[2]}}),
                                                   kL, machine::ErrorMode::Nominal);
    const machine::ToolPose before = machine::forward(*ac_machine(),
                                                      machine::positions(*ac_machine(), {{'X', n50.end_mm[0]}, {'Y', n50.end_mm[1]},
                                                                                         {'Z', n50.end_mm[2]}, {'A', -30}, {'C', 180}}),
                                                      kL, machine::ErrorMode::Nominal);
    CHECK((end.tip_mm() - Eigen::Vector3d(before.tip_mm().x(), before.tip_mm().y(), -570)).norm() < 1e-9);
    CHECK(std::abs(n70.end_mm[1] - n70.start_mm[1]) > 1);
    CHECK((end.axis() - before.axis()).norm() < 1e-9);
    CHECK(n70.end_deg[0] == Approx(-30).margin(1e-9));
    CHECK(n70.end_deg[2] == Approx(180).margin(1e-9));
}
