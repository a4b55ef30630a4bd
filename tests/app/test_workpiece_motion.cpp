// A log of machine axes through a machine definition into the tool's motion against the part
// (app/workpiece_motion.hpp, docs/five_axis.md section 2.3), checked against closed forms: a table
// turning under a standing tool feeds it at omega times its distance from the C line (test T2),
// the spindle speed against the part is the spindle's less the table's turn, a path commanded
// through a turned table is the same path and gives the same forces as the three-axis run, and a
// tilted tool or a missing channel is refused.
#include "app/predict_run.hpp"
#include "app/workpiece_motion.hpp"
#include "app_fixtures.hpp"
#include "force_model/engine_fixtures.hpp"
#include "machine/machine.hpp"
#include "machine/kinematics.hpp"
#include "motion_io/commanded.hpp"
#include "motion_io/nc_program.hpp"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <unistd.h>
#include <numbers>

using namespace cutload;

namespace {

std::shared_ptr<const machine::Machine> ac_table_table() {
    return app::load_machine_definition(std::string(CUTLOAD_SOURCE_DIR) + "/data/machines/ac_table_table.json");
}

// The bundled AC machine's C line passes through (-350, -275) at home.
constexpr double kCx = -350, kCy = -275;

// Machine axes held at x, y, z with A at a_deg and C turning at c_rate_deg_s from c0_deg; 1 ms
// samples, spindle at 10 000 rpm (M03).
motion_io::MotionModel table_turn(double x, double y, double z, double a_deg, double c0_deg, double c_rate_deg_s,
                                  double duration_s = 0.5) {
    motion_io::MotionModel m;
    m.step_s = 0.001;
    const auto n = std::size_t(std::lround(duration_s / m.step_s)) + 1;
    m.block_names = {"N10"};
    for (std::size_t i = 0; i < n; ++i) {
        const double t = double(i) * m.step_s;
        m.t_s.push_back(t);
        m.x_mm.push_back(x), m.y_mm.push_back(y), m.z_mm.push_back(z);
        m.vx_mm_s.push_back(0), m.vy_mm_s.push_back(0), m.vz_mm_s.push_back(0);
        m.spindle_rpm.push_back(10000);
        m.spindle_angle_deg.push_back(60000 * t);
        m.block.push_back(0);
        m.rot_deg[0].push_back(a_deg), m.rot_vel_deg_s[0].push_back(0);
        m.rot_deg[2].push_back(c0_deg + c_rate_deg_s * t), m.rot_vel_deg_s[2].push_back(c_rate_deg_s);
    }
    m.session_start = {0};
    return m;
}

// A three-axis motion as the log of the AC machine standing at A = C = 0.
motion_io::MotionModel three_axis_with_rotary(motion_io::MotionModel m) {
    m.rot_deg[0].assign(m.size(), 0.0), m.rot_vel_deg_s[0].assign(m.size(), 0.0);
    m.rot_deg[2].assign(m.size(), 0.0), m.rot_vel_deg_s[2].assign(m.size(), 0.0);
    return m;
}

// `first` followed by `second` as a later session whose times are second's shifted by
// `shift_s` (less than first's end: the sessions overlap in time, as in a restart dump). Both
// name their blocks alike.
motion_io::MotionModel two_sessions(motion_io::MotionModel first, const motion_io::MotionModel& second, double shift_s) {
    const std::size_t n1 = first.size();
    auto append = [](std::vector<double>& a, const std::vector<double>& b) { a.insert(a.end(), b.begin(), b.end()); };
    for (double t : second.t_s) first.t_s.push_back(t + shift_s);
    append(first.x_mm, second.x_mm), append(first.y_mm, second.y_mm), append(first.z_mm, second.z_mm);
    append(first.vx_mm_s, second.vx_mm_s), append(first.vy_mm_s, second.vy_mm_s), append(first.vz_mm_s, second.vz_mm_s);
    append(first.spindle_rpm, second.spindle_rpm), append(first.spindle_angle_deg, second.spindle_angle_deg);
    first.block.insert(first.block.end(), second.block.begin(), second.block.end());
    for (std::size_t k = 0; k < 3; ++k)
        if (first.has_rotary(int(k))) append(first.rot_deg[k], second.rot_deg[k]), append(first.rot_vel_deg_s[k], second.rot_vel_deg_s[k]);
    first.session_start = {0, n1};
    return first;
}

// The machine axes (the bundled AC machine, A = 0, C = c_deg held) that put the tip on the
// workpiece path `tip` (a three-axis motion): each sample by inverse kinematics (a vertical tool
// on a C table leaves C where it was), the rates by the map's derivative.
motion_io::MotionModel axes_for(const motion_io::MotionModel& tip, const machine::Machine& machine, double c_deg) {
    machine::AxisPositions previous = machine::positions(machine, {{'C', c_deg}, {'A', 0.0}});
    const std::size_t ix = machine.index_of('X'), iy = machine.index_of('Y'), iz = machine.index_of('Z'),
                      ic = machine.index_of('C');
    motion_io::MotionModel axes = tip;
    axes.rot_deg[0].assign(axes.size(), 0.0), axes.rot_vel_deg_s[0].assign(axes.size(), 0.0);
    axes.rot_deg[2].assign(axes.size(), c_deg), axes.rot_vel_deg_s[2].assign(axes.size(), 0.0);
    const Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
    for (std::size_t i = 0; i < axes.size(); ++i) {
        const Eigen::Vector3d p(tip.x_mm[i], tip.y_mm[i], tip.z_mm[i]);
        const Eigen::Vector3d v(tip.vx_mm_s[i], tip.vy_mm_s[i], tip.vz_mm_s[i]);
        const machine::AxisPositions q = machine::inverse(machine, p, up, 0, previous);
        const machine::AxisPositions q1 = machine::inverse(machine, p + 1e-3 * v, up, 0, q);
        REQUIRE(q.value[ic] == Approx(c_deg));
        axes.x_mm[i] = q.value[ix], axes.y_mm[i] = q.value[iy], axes.z_mm[i] = q.value[iz];
        axes.vx_mm_s[i] = (q1.value[ix] - q.value[ix]) / 1e-3;
        axes.vy_mm_s[i] = (q1.value[iy] - q.value[iy]) / 1e-3;
        axes.vz_mm_s[i] = (q1.value[iz] - q.value[iz]) / 1e-3;
        previous = q;
    }
    return axes;
}

// Rows of a constant workpiece force (100, -40, 7) N at the times given.
void add_constant_rows(std::vector<force_model::ForceSample>& rows, double t0_s, double t1_s, bool t1_included) {
    for (double t = t0_s; t1_included ? t <= t1_s : t < t1_s; t += 0.000337) {
        force_model::ForceSample s;
        s.t_s = t, s.fx_N = 100, s.fy_N = -40, s.fz_N = 7;
        rows.push_back(s);
    }
}

// R_bed = R_z(C): F_M = (Fx cos C + Fy sin C, -Fx sin C + Fy cos C, Fz), with C = 10 + 30 t deg in
// the first session's rows and 200 deg in the second's.
void require_turned_by_c(const std::vector<force_model::ForceSample>& rows, std::size_t first_session_rows) {
    for (std::size_t i = 0; i < rows.size(); ++i) {
        const force_model::ForceSample& s = rows[i];
        INFO("row " << i << ", t = " << s.t_s);
        const double c = (i < first_session_rows ? 10 + 30 * s.t_s : 200) * std::numbers::pi / 180;
        REQUIRE(s.fx_machine_N == Approx(100 * std::cos(c) - 40 * std::sin(c)).epsilon(1e-6));
        REQUIRE(s.fy_machine_N == Approx(-100 * std::sin(c) - 40 * std::cos(c)).epsilon(1e-6));
        REQUIRE(s.fz_machine_N == 7);
    }
}

}  // namespace

TEST_CASE("workpiece motion: a C table turning 30 deg/s feeds a tool 100 mm off its line at 3141.6 mm/min",
          "[five_axis][workpiece_motion]") {
    const auto machine = ac_table_table();
    const double z = -400;
    const motion_io::MotionModel axes = table_turn(kCx + 100, kCy, z, 0, 0, 30);
    const motion_io::MotionModel w = app::workpiece_motion(axes, *machine, 0);
    REQUIRE(w.size() == axes.size());
    const double expected_mm_min = 100 * 30 * std::numbers::pi / 180 * 60;   // 3141.59 mm/min
    for (std::size_t i = 0; i < w.size(); i += 50) {
        INFO("t = " << w.t_s[i]);
        const double speed_mm_min = std::hypot(w.vx_mm_s[i], w.vy_mm_s[i], w.vz_mm_s[i]) * 60;
        CHECK(speed_mm_min == Approx(expected_mm_min).epsilon(1e-6));
        // On the circle of radius 100 about the C line, at the table's height.
        CHECK(std::hypot(w.x_mm[i] - kCx, w.y_mm[i] - kCy) == Approx(100).epsilon(1e-12));
        CHECK(w.z_mm[i] == Approx(z).margin(1e-9));
        // Tangent to the circle: no radial component.
        CHECK(((w.x_mm[i] - kCx) * w.vx_mm_s[i] + (w.y_mm[i] - kCy) * w.vy_mm_s[i]) == Approx(0).margin(1e-6));
        // +C turns the tool right-handed about +Z relative to the part (ISO 841), against the
        // clockwise (M03) cutter: 30 deg/s takes 5 rpm off its speed against the part.
        CHECK(w.spindle_rpm[i] == Approx(9995).epsilon(1e-12));
    }
    // The angle against the part changes at the speed against the part.
    const double rate_rpm = (w.spindle_angle_deg.back() - w.spindle_angle_deg.front()) / (w.t_s.back() - w.t_s.front()) / 6;
    CHECK(rate_rpm == Approx(w.spindle_rpm[w.size() / 2]).epsilon(1e-9));
    // ISO 841: a positive C move turns the tool right-handed about +Z relative to the part, so the
    // tip runs counter-clockwise round the C line (the table itself turns clockwise).
    const double cross_z = (w.x_mm[0] - kCx) * w.vy_mm_s[0] - (w.y_mm[0] - kCy) * w.vx_mm_s[0];
    CHECK(cross_z > 0);
}

TEST_CASE("workpiece motion: a machine at rest in its home orientation is the three-axis motion",
          "[five_axis][workpiece_motion]") {
    const auto machine = ac_table_table();
    const motion_io::MotionModel axes = table_turn(-120.5, -40.25, -300, 0, 0, 0);
    const motion_io::MotionModel w = app::workpiece_motion(axes, *machine, 0);
    for (std::size_t i = 0; i < w.size(); ++i) {
        CHECK(w.x_mm[i] == Approx(axes.x_mm[i]).margin(1e-9));
        CHECK(w.y_mm[i] == Approx(axes.y_mm[i]).margin(1e-9));
        CHECK(w.z_mm[i] == Approx(axes.z_mm[i]).margin(1e-9));
        CHECK(w.spindle_angle_deg[i] == axes.spindle_angle_deg[i]);
        CHECK(w.spindle_rpm[i] == axes.spindle_rpm[i]);
    }
}

TEST_CASE("workpiece motion: the machine's geometric errors move the tip by what forward kinematics gives",
          "[five_axis][workpiece_motion]") {
    // The bundled error set leans the tool by microradians (squareness, rotation errors): the
    // commanded orientation stays vertical, so the run is taken, with the tip where the errors
    // put it.
    const std::string dir = std::string(CUTLOAD_SOURCE_DIR) + "/data/machines/";
    const auto nominal = app::load_machine_definition(dir + "ac_table_table.json");
    const auto with_errors = app::load_machine_definition(dir + "ac_table_table.json", dir + "ac_table_table_errors.json");
    REQUIRE(with_errors->has_errors());
    const motion_io::MotionModel axes = table_turn(kCx + 100, kCy, -400, 0, 0, 30);
    const motion_io::MotionModel a = app::workpiece_motion(axes, *nominal, 0);
    const motion_io::MotionModel b = app::workpiece_motion(axes, *with_errors, 0);
    double largest_mm = 0;
    for (std::size_t i = 0; i < axes.size(); i += 25) {
        const machine::AxisPositions q =
            machine::positions(*with_errors, {{'X', axes.x_mm[i]}, {'Y', axes.y_mm[i]}, {'Z', axes.z_mm[i]},
                                              {'A', axes.rot_deg[0][i]}, {'C', axes.rot_deg[2][i]}});
        const Eigen::Vector3d d = machine::forward(*with_errors, q, 0).tip_mm() -
                                  machine::forward(*with_errors, q, 0, machine::ErrorMode::Nominal).tip_mm();
        CHECK(b.x_mm[i] - a.x_mm[i] == Approx(d.x()).margin(1e-9));
        CHECK(b.y_mm[i] - a.y_mm[i] == Approx(d.y()).margin(1e-9));
        CHECK(b.z_mm[i] - a.z_mm[i] == Approx(d.z()).margin(1e-9));
        largest_mm = std::max(largest_mm, d.norm());
    }
    CHECK(largest_mm > 1e-3);   // the errors do move the tip, by micrometres
}

TEST_CASE("workpiece motion: a tilted tool and a missing rotary channel are refused, naming what and where",
          "[five_axis][workpiece_motion][errors]") {
    const auto machine = ac_table_table();
    try {
        app::workpiece_motion(table_turn(-200, -200, -300, -10, 0, 0), *machine, 0);
        FAIL("a tool tilted by A = -10 deg was taken");
    } catch (const app::WorkpieceMotionError& e) {
        CHECK_THAT(e.what(), Catch::Contains("t = 0.0000 s") && Catch::Contains("leans 10 deg") &&
                                 Catch::Contains("multi-direction stock"));
    }
    motion_io::MotionModel no_c = table_turn(-200, -200, -300, 0, 0, 0);
    no_c.rot_deg[2].clear(), no_c.rot_vel_deg_s[2].clear();
    try {
        app::workpiece_motion(no_c, *machine, 0);
        FAIL("a log without C was taken for an AC machine");
    } catch (const app::WorkpieceMotionError& e) {
        CHECK_THAT(e.what(), Catch::Contains("rotary axis C") && Catch::Contains("column 'c'"));
    }
    CHECK_THROWS_WITH(app::load_machine_definition(std::string(CUTLOAD_SOURCE_DIR) + "/data/demo_run.json"),
                      Catch::Contains("demo_run.json"));
}

TEST_CASE("workpiece motion: a cut commanded through the table turned 90 deg gives the three-axis forces",
          "[five_axis][workpiece_motion][physics]") {
    // The cut, in workpiece coordinates: a side cut along X at ae 1 mm, ap 3 mm (the seed's), on a
    // stock placed about the C line.
    using enginetest::legs_motion;
    force_model::RunSpec spec = enginetest::base_spec(40, 20, 10);
    spec.offset_mm[0] = -kCx + 20, spec.offset_mm[1] = -kCy + 10, spec.offset_mm[2] = 310;   // stock (0..40, 0..20, 0..10)
    const double y_w = kCy - 10 - 3, z_w = -303;   // tool centre 3 mm outside y = 0: ae 1 mm; tip 3 mm below the top
    const motion_io::MotionModel three_axis =
        legs_motion({kCx - 30, y_w, z_w}, {{{kCx + 30, y_w, z_w}, 3000, "N10"}});

    // The same path through the machine with C at 90 deg.
    const auto machine = ac_table_table();
    const motion_io::MotionModel axes = axes_for(three_axis, *machine, 90);
    // The logged axes really are turned: X moves along the workpiece's Y.
    CHECK(std::abs(axes.y_mm.back() - axes.y_mm.front()) == Approx(60).epsilon(1e-9));
    CHECK(std::abs(axes.x_mm.back() - axes.x_mm.front()) < 1e-9);

    const motion_io::MotionModel w = app::workpiece_motion(axes, *machine, 0);
    for (std::size_t i = 0; i < w.size(); ++i) {
        REQUIRE(w.x_mm[i] == Approx(three_axis.x_mm[i]).margin(1e-9));
        REQUIRE(w.y_mm[i] == Approx(three_axis.y_mm[i]).margin(1e-9));
        REQUIRE(w.vx_mm_s[i] == Approx(three_axis.vx_mm_s[i]).margin(1e-6));
    }
    for (const force_model::Device d : {force_model::Device::Cpu, force_model::Device::OpenCL}) {
        if (d == force_model::Device::OpenCL && !enginetest::opencl_available()) continue;
        const force_model::Prediction plain = enginetest::run_on(three_axis, spec, d);
        const force_model::Prediction turned = enginetest::run_on(w, spec, d);
        REQUIRE(plain.blocks.size() == 1);
        REQUIRE(turned.blocks.size() == 1);
        REQUIRE(plain.blocks[0].peak_force_N > 100);   // it cuts
        CHECK(turned.blocks[0].peak_force_N == Approx(plain.blocks[0].peak_force_N).epsilon(1e-3));
        CHECK(turned.blocks[0].mean_force_N == Approx(plain.blocks[0].mean_force_N).epsilon(1e-3));
        CHECK(turned.blocks[0].removed_mm3 == Approx(plain.blocks[0].removed_mm3).epsilon(1e-3));
        if (d != force_model::Device::Cpu) continue;

        // Machine axes (test T3's second half). The table turned +90 deg about C maps machine
        // axes into workpiece axes by R_bed = R_z(+90) (the machine suite: a tip d from the C line
        // at C = 0 is at R_z(90) d at C = 90), so F_M = R_z(90)^T F_W = R_z(-90) F_W:
        // (Fx, Fy, Fz) -> (Fy, -Fx, Fz). A feed force against the part's +X (the cut runs along it)
        // is then along the machine's +Y, whose axis runs the other way (Y fell by 60 mm above).
        std::vector<force_model::ForceSample> rows = turned.samples;
        app::MachineAxesForces(axes, machine).apply(rows);
        const machine::AxisPositions q90 = machine::positions(*machine, {{'C', 90.0}, {'A', 0.0}});
        const Eigen::Matrix3d R = machine::bed_to_workpiece(*machine, q90).R;
        double largest_N = 0, mean_fy_machine_N = 0;
        for (const force_model::ForceSample& s : rows) {
            const double scale = std::hypot(s.fx_N, s.fy_N, s.fz_N) * 1e-9 + 1e-30;
            const Eigen::Vector3d f_m = R.transpose() * Eigen::Vector3d(s.fx_N, s.fy_N, s.fz_N);
            REQUIRE(s.fx_machine_N == Approx(f_m.x()).epsilon(1e-9).margin(scale));
            REQUIRE(s.fy_machine_N == Approx(f_m.y()).epsilon(1e-9).margin(scale));
            REQUIRE(s.fz_machine_N == Approx(f_m.z()).epsilon(1e-9).margin(scale));
            REQUIRE(s.fx_machine_N == Approx(s.fy_N).epsilon(1e-9).margin(scale));    // by hand
            REQUIRE(s.fy_machine_N == Approx(-s.fx_N).epsilon(1e-9).margin(scale));
            REQUIRE(s.fz_machine_N == s.fz_N);
            largest_N = std::max(largest_N, double(std::hypot(s.fx_N, s.fy_N)));
            mean_fy_machine_N += s.fy_machine_N / double(rows.size());
        }
        CHECK(largest_N > 100);   // the comparison saw real forces
        // The workpiece forces of the same cut at C = 0 (no turn) are the machine's own: the
        // feed force along the part's X is along the machine's X there, and along Y here.
        std::vector<force_model::ForceSample> at_rest = plain.samples;
        app::MachineAxesForces(three_axis_with_rotary(three_axis), machine).apply(at_rest);
        double mean_fx_rest_N = 0;
        for (const force_model::ForceSample& s : at_rest) {
            // Identical, not merely close: R_bed is the identity at rest.
            REQUIRE(s.fx_machine_N == s.fx_N);
            REQUIRE(s.fy_machine_N == s.fy_N);
            REQUIRE(s.fz_machine_N == s.fz_N);
            mean_fx_rest_N += s.fx_N / double(at_rest.size());
        }
        CHECK(mean_fy_machine_N == Approx(-mean_fx_rest_N).epsilon(2e-3));
    }
}

TEST_CASE("machine-axis forces: each row is turned by the table's angle at its own time, across sessions",
          "[five_axis][workpiece_motion]") {
    // C turning 30 deg/s from 10 deg: rows between the 1 ms samples see C at their own time, not
    // at the nearest sample. R_bed = R_z(C), so F_M = (Fx cos C + Fy sin C, -Fx sin C + Fy cos C, Fz).
    const auto machine = ac_table_table();
    // A second session starts back in time (a restart dump): C stands at 200 deg there.
    const motion_io::MotionModel axes =
        two_sessions(table_turn(kCx + 100, kCy, -400, 0, 10, 30, 0.1), table_turn(kCx + 100, kCy, -400, 0, 200, 0, 0.05), 0);
    const std::size_t n1 = axes.session_start[1];

    std::vector<force_model::ForceSample> rows;
    add_constant_rows(rows, 0.0, 0.1, false);
    const std::size_t first_session_rows = rows.size();
    add_constant_rows(rows, 0.0, 0.05, true);
    // As the engine says (PredictOptions::session_begins); the rows go in two pieces, as streamed.
    app::MachineAxesForces turn(axes, machine);
    turn.begin_session(0, n1, 0);
    turn.begin_session(n1, axes.size(), first_session_rows);
    turn.apply(std::span(rows).first(100));
    turn.apply(std::span(rows).subspan(100));
    require_turned_by_c(rows, first_session_rows);
}

TEST_CASE("machine-axis forces: sessions overlapping in time each take their own C, by the engine's word on their rows",
          "[five_axis][workpiece_motion]") {
    const auto machine = ac_table_table();
    SECTION("rows as the engine writes them: the first session's tail has none") {
        // C turning 30 deg/s from 10 deg over 0.1 s; then a restart dump 0.05 s long with C held
        // at 200 deg, whose times (0.04 .. 0.09 s) lie inside the first session's. The first
        // session's rows stop at 0.03 s (no angle step in its last intervals: a slow spindle in
        // material), so the second's first row comes later than the first's last: by time alone it
        // continues the first session.
        const motion_io::MotionModel axes =
            two_sessions(table_turn(kCx + 100, kCy, -400, 0, 10, 30, 0.1), table_turn(kCx + 100, kCy, -400, 0, 200, 0, 0.05), 0.04);
        const std::size_t n1 = axes.session_start[1];
        std::vector<force_model::ForceSample> rows;
        add_constant_rows(rows, 0.0, 0.03, false);
        const std::size_t first_session_rows = rows.size();
        add_constant_rows(rows, 0.04, 0.09, true);
        app::MachineAxesForces turn(axes, machine);
        turn.begin_session(0, n1, 0);
        turn.begin_session(n1, axes.size(), first_session_rows);
        turn.apply(rows);
        require_turned_by_c(rows, first_session_rows);
        // Without the engine's word, a model of two sessions is refused rather than guessed.
        std::vector<force_model::ForceSample> unplaced(rows.begin(), rows.begin() + 3);
        CHECK_THROWS_AS(app::MachineAxesForces(axes, machine).apply(unplaced), std::logic_error);
        CHECK_THROWS_AS(app::MachineAxesForces(axes, machine).begin_session(1, n1, 0), std::invalid_argument);
    }
    SECTION("through the engine: a side cut at C = 0, then 1 mm deeper at C = 90 in a session half as late") {
        // The T3 side cut (along X at ae 1 mm, ap 3 mm) on the stock about the C line.
        using enginetest::legs_motion;
        force_model::RunSpec spec = enginetest::base_spec(40, 20, 10);
        spec.offset_mm[0] = -kCx + 20, spec.offset_mm[1] = -kCy + 10, spec.offset_mm[2] = 310;
        const double y_w = kCy - 10 - 3, z_w = -303;
        const motion_io::MotionModel cut = legs_motion({kCx - 30, y_w, z_w}, {{{kCx + 30, y_w, z_w}, 3000, "N10"}});
        motion_io::MotionModel deeper = cut;
        for (double& z : deeper.z_mm) z -= 1;
        const double half_s = 0.5 * cut.t_s.back();
        const motion_io::MotionModel axes =
            two_sessions(three_axis_with_rotary(cut), axes_for(deeper, *machine, 90), half_s);
        const std::size_t n1 = axes.session_start[1];
        const motion_io::MotionModel w = app::workpiece_motion(axes, *machine, 0);

        // The first session's rows, counted apart: it is walked first, on the fresh stock, so its
        // rows are the same alone as before the second.
        motion_io::MotionModel first_alone = app::workpiece_motion(three_axis_with_rotary(cut), *machine, 0);
        const std::size_t first_rows = enginetest::run_on(first_alone, spec, force_model::Device::Cpu).samples.size();

        // Wired as predict_run wires it.
        app::MachineAxesForces turn(axes, machine);
        std::vector<std::array<std::size_t, 3>> said;
        force_model::PredictOptions po;
        po.device = force_model::Device::Cpu;
        po.session_begins = [&](std::size_t begin, std::size_t end, std::size_t first_row) {
            said.push_back({begin, end, first_row});
            turn.begin_session(begin, end, first_row);
        };
        force_model::Prediction p = force_model::predict(w, spec, po);
        turn.apply(p.samples);
        REQUIRE(said == std::vector<std::array<std::size_t, 3>>{{0, n1, 0}, {n1, axes.size(), first_rows}});
        REQUIRE(p.samples.size() > first_rows);
        // The sessions do overlap in their rows' times.
        CHECK(p.samples[first_rows].t_s < p.samples[first_rows - 1].t_s);
        double largest_first_N = 0, largest_second_N = 0;
        for (std::size_t i = 0; i < p.samples.size(); ++i) {
            const force_model::ForceSample& s = p.samples[i];
            INFO("row " << i << ", t = " << s.t_s);
            if (i < first_rows) {
                // C = 0: R_bed is the identity, the forces are copied.
                REQUIRE(s.fx_machine_N == s.fx_N);
                REQUIRE(s.fy_machine_N == s.fy_N);
                REQUIRE(s.fz_machine_N == s.fz_N);
                largest_first_N = std::max(largest_first_N, double(std::hypot(s.fx_N, s.fy_N)));
            } else {
                // C = 90: (Fx, Fy, Fz) -> (Fy, -Fx, Fz).
                const double scale = std::hypot(s.fx_N, s.fy_N, s.fz_N) * 1e-6 + 1e-30;
                REQUIRE(s.fx_machine_N == Approx(s.fy_N).margin(scale));
                REQUIRE(s.fy_machine_N == Approx(-s.fx_N).margin(scale));
                REQUIRE(s.fz_machine_N == s.fz_N);
                largest_second_N = std::max(largest_second_N, double(std::hypot(s.fx_N, s.fy_N)));
            }
        }
        CHECK(largest_first_N > 100);    // both sessions cut
        CHECK(largest_second_N > 10);
    }
}

TEST_CASE("workpiece motion: a squareness error and a C-line offset move the cut by the closed form, and its forces "
          "with it",
          "[five_axis][workpiece_motion][physics]") {
    // The T3 side cut (along X at ae 1 mm, ap 3 mm) at A = C = 0, where the workpiece frame is the
    // machine's, on a machine with two errors worked out by hand in tests/machine: the X-Y
    // squareness EC0X = g turns the X travel about Z through the home origin, and EY0C = d puts
    // the C line d off the A line in Y, the tool -d against the table. The tip is then moved by
    //   (X (cos g - 1), X sin g - d, 0),
    // and at X = -380 .. -320 mm that takes 0.31 .. 0.34 mm off the 1 mm radial depth.
    const double g = 500e-6, d_mm = 0.150;
    const std::filesystem::path errors =
        std::filesystem::temp_directory_path() / ("cutload_squareness_" + std::to_string(::getpid()) + ".json");
    {
        std::ofstream out(errors);
        out << R"({"X": {"EC0X_urad": 500}, "C": {"EY0C_um": 150}})";
    }
    const std::string dir = std::string(CUTLOAD_SOURCE_DIR) + "/data/machines/";
    const auto nominal = app::load_machine_definition(dir + "ac_table_table.json");
    const auto machine = app::load_machine_definition(dir + "ac_table_table.json", errors.string());
    std::filesystem::remove(errors);

    using enginetest::legs_motion;
    force_model::RunSpec spec = enginetest::base_spec(40, 20, 10);
    spec.offset_mm[0] = -kCx + 20, spec.offset_mm[1] = -kCy + 10, spec.offset_mm[2] = 310;
    const double y_w = kCy - 10 - 3, z_w = -303;
    const motion_io::MotionModel three_axis = legs_motion({kCx - 30, y_w, z_w}, {{{kCx + 30, y_w, z_w}, 3000, "N10"}});
    motion_io::MotionModel axes = three_axis;
    axes.rot_deg[0].assign(axes.size(), 0.0), axes.rot_vel_deg_s[0].assign(axes.size(), 0.0);
    axes.rot_deg[2].assign(axes.size(), 0.0), axes.rot_vel_deg_s[2].assign(axes.size(), 0.0);

    // The reference: the three-axis path moved by the closed form, its velocity by its derivative.
    motion_io::MotionModel moved = three_axis;
    for (std::size_t i = 0; i < moved.size(); ++i) {
        const double X = three_axis.x_mm[i], vX = three_axis.vx_mm_s[i];
        moved.x_mm[i] += X * (std::cos(g) - 1), moved.y_mm[i] += X * std::sin(g) - d_mm;
        moved.vx_mm_s[i] = vX * std::cos(g), moved.vy_mm_s[i] += vX * std::sin(g);
    }
    const motion_io::MotionModel w = app::workpiece_motion(axes, *machine, 0);
    const motion_io::MotionModel w0 = app::workpiece_motion(axes, *nominal, 0);
    REQUIRE(w.size() == moved.size());
    for (std::size_t i = 0; i < w.size(); ++i) {
        INFO("sample " << i << " at X = " << three_axis.x_mm[i]);
        REQUIRE(w.x_mm[i] == Approx(moved.x_mm[i]).margin(1e-6));
        REQUIRE(w.y_mm[i] == Approx(moved.y_mm[i]).margin(1e-6));
        REQUIRE(w.z_mm[i] == Approx(moved.z_mm[i]).margin(1e-6));
        REQUIRE(w.vy_mm_s[i] == Approx(moved.vy_mm_s[i]).margin(1e-6));
        REQUIRE(w0.y_mm[i] == Approx(three_axis.y_mm[i]).margin(1e-9));
    }
    for (const force_model::Device dev : {force_model::Device::Cpu, force_model::Device::OpenCL}) {
        if (dev == force_model::Device::OpenCL && !enginetest::opencl_available()) continue;
        const force_model::Prediction plain = enginetest::run_on(w0, spec, dev);
        const force_model::Prediction reference = enginetest::run_on(moved, spec, dev);
        const force_model::Prediction errored = enginetest::run_on(w, spec, dev);
        REQUIRE(errored.blocks.size() == 1);
        REQUIRE(reference.blocks.size() == 1);
        REQUIRE(plain.blocks.size() == 1);
        // The errors' forces are those of the moved path...
        CHECK(errored.blocks[0].peak_force_N == Approx(reference.blocks[0].peak_force_N).epsilon(1e-3));
        CHECK(errored.blocks[0].mean_force_N == Approx(reference.blocks[0].mean_force_N).epsilon(1e-3));
        CHECK(errored.blocks[0].removed_mm3 == Approx(reference.blocks[0].removed_mm3).epsilon(1e-3));
        // ... and differ from the nominal machine's: a third of the radial depth is gone, and with it
        // about a third of the chip volume.
        const double removed_ratio = errored.blocks[0].removed_mm3 / plain.blocks[0].removed_mm3;
        INFO("removed " << errored.blocks[0].removed_mm3 << " mm3 against " << plain.blocks[0].removed_mm3);
        CHECK(removed_ratio > 0.60);
        CHECK(removed_ratio < 0.75);
        CHECK(errored.blocks[0].mean_force_N < 0.9 * plain.blocks[0].mean_force_N);
    }
}

// A machine-axis program names only the axes it moves: its commanded motion holds those, by the
// axis's letter. Laid out as the machine's log (what turning_motion reads), each rotary axis sits
// in the channel it reads, and one the program never names stays where the program starts it.
TEST_CASE("program axes as a log: an axis the program leaves out holds its start, each in its channel",
          "[five_axis][turning]") {
    const auto base = ac_table_table();
    motion_io::NcReadOptions ro;
    ro.rotary_axes = app::machine_rotary_axes(*base);
    REQUIRE(ro.rotary_axes == "AC");
    ro.start_mm = std::array<double, 3>{0, 0, 100};
    ro.work_offsets_mm["G54"] = {0, 0, 0};
    ro.start_deg = {-30, 0, 10};   // A held at -30 by an earlier set-up, C from 10
    const std::string text = "G21 G90 G54\nN10 G1 X10 Y0 Z100 C90 F600\nN20 G1 X20 C170\n";
    const motion_io::NcProgram program = motion_io::parse_nc_program(text, "c_only.nc", ro);
    motion_io::CommandedOptions co;
    const motion_io::MotionModel as_read = motion_io::commanded_motion(program, co);
    REQUIRE_FALSE(as_read.has_rotary(0));   // the program never names A
    REQUIRE(as_read.has_rotary(2));
    // As read, the chain cannot take it: it wants A's channel.
    CHECK_THROWS_WITH(app::turning_motion(as_read, *base, 120), Catch::Contains("rotary axis A needs column 'a'"));

    SECTION("each axis reads the channel of its own letter") {
        motion_io::MotionModel axes = as_read;
        app::program_axes_as_log(axes, program, *base);
        REQUIRE(axes.has_rotary(0));
        CHECK_FALSE(axes.has_rotary(1));
        REQUIRE(axes.rot_deg[0].size() == axes.size());
        CHECK(std::all_of(axes.rot_deg[0].begin(), axes.rot_deg[0].end(), [](double a) { return a == -30; }));
        CHECK(std::all_of(axes.rot_vel_deg_s[0].begin(), axes.rot_vel_deg_s[0].end(), [](double v) { return v == 0; }));
        CHECK(axes.rot_deg[2] == as_read.rot_deg[2]);
        CHECK(axes.rot_deg[2].front() == Approx(10));
        CHECK(axes.rot_deg[2].back() == Approx(170));
        // Through the chain: no refusal for the axis the program left out.
        CHECK_NOTHROW(app::turning_motion(axes, *base, 120));
        // The log's own start angles by letter are what the reader was given.
        const std::array<double, 3> start = app::rotary_start_by_letter(axes, *base);
        CHECK(start[0] == -30);
        CHECK(start[2] == Approx(10));
    }
    SECTION("an axis that reads another channel is laid out there, and its start read from there") {
        machine::Machine swapped = *base;
        for (machine::Axis& a : swapped.chain)
            if (a.name == 'A') a.channel = "b";   // the controller exports A as column b
        motion_io::MotionModel axes = as_read;
        app::program_axes_as_log(axes, program, swapped);
        CHECK_FALSE(axes.has_rotary(0));
        REQUIRE(axes.has_rotary(1));
        CHECK(axes.rot_deg[1].front() == -30);
        CHECK(axes.rot_deg[2] == as_read.rot_deg[2]);
        CHECK_NOTHROW(app::turning_motion(axes, swapped, 120));
        const std::array<double, 3> start = app::rotary_start_by_letter(axes, swapped);
        CHECK(start[0] == -30);   // A's letter, read from channel b
        CHECK(start[1] == 0);
        // A log without A's channel is refused by name, as turning_motion refuses it.
        motion_io::MotionModel no_b = axes;
        no_b.rot_deg[1].clear();
        no_b.rot_vel_deg_s[1].clear();
        CHECK_THROWS_WITH(app::rotary_start_by_letter(no_b, swapped), Catch::Contains("rotary axis A needs column 'b'"));
    }
}

// The table turns about a tip that sits on its C line: the tip stays put against the part. The tip
// path holds it there for the block's time, so both programs time the block alike. (With the
// pivots at the machine's zero and the tip at X0 Y0 the tip's pieces are exactly 0 long: such a
// piece, neither moving nor turning, was timed as none.)
TEST_CASE("turning program: a turn about a tip that stays put keeps its time on the tip path", "[five_axis][turning]") {
    nlohmann::json def = nlohmann::json::parse(apptest::read_text(std::string(CUTLOAD_SOURCE_DIR) + "/data/machines/ac_table_table.json"));
    for (auto& axis : def["workpiece_side"]) axis["pivot_mm"] = {0, 0, 0};
    const machine::Machine m = machine::parse_machine(def);
    const machine::Machine* machine = &m;
    motion_io::NcReadOptions ro;
    ro.rotary_axes = app::machine_rotary_axes(*machine);
    ro.start_mm = std::array<double, 3>{0, 0, -300};
    ro.work_offsets_mm["G54"] = {0, 0, 0};
    // 1/F minutes each: N20 turns C a quarter in 1 s, N30 a half in 2 s, the tip on the C line.
    // N50 moves the tip off the C line while C turns on: its tip speed grows along the block.
    const std::string text = "G21 G90 G54\nN10 G1 X0 Y0 Z-300 F600\nN20 G93 G1 C90 F60\nN30 C270 F30\n"
                             "N40 G94 G1 X-10 F600\nN50 G93 G1 X-40 C450 F30\n";
    const motion_io::NcProgram axes = motion_io::parse_nc_program(text, "turn_in_place.nc", ro);
    const motion_io::NcProgram tip = app::turning_workpiece_program(axes, *machine, 120, 30000);
    motion_io::CommandedOptions co;
    const std::vector<double> axes_s = motion_io::commanded_durations_s(axes, co);
    const std::vector<double> tip_s = motion_io::commanded_durations_s(tip, co);
    std::map<std::string, double> by_axes, by_tip;
    for (std::size_t i = 0; i < axes.blocks.size(); ++i) by_axes[axes.blocks[i].name] += axes_s[i];
    for (std::size_t i = 0; i < tip.blocks.size(); ++i) by_tip[tip.blocks[i].name] += tip_s[i];
    CHECK(by_axes["N20"] == Approx(1.0));
    CHECK(by_axes["N30"] == Approx(2.0));
    for (const auto& [name, s] : by_axes) {
        INFO("block " << name);
        CHECK(by_tip[name] == Approx(s).margin(1e-12));
    }
    // N50's pieces all carry the block's mean tip speed, the one programmed feed the comparison reads.
    double n50_mm = 0;
    std::vector<double> n50_feeds;
    for (const motion_io::NcBlock& b : tip.blocks)
        if (b.name == "N50") {
            n50_mm += std::hypot(b.end_mm[0] - b.start_mm[0], b.end_mm[1] - b.start_mm[1], b.end_mm[2] - b.start_mm[2]);
            n50_feeds.push_back(b.feed_mm_min);
        }
    REQUIRE(n50_feeds.size() > 10);
    CHECK(n50_mm > 30);   // 30 mm along X, more along the turning spiral
    for (const double f : n50_feeds) CHECK(f == Approx(n50_mm / 2.0 * 60.0).epsilon(1e-9));
    // The tip does not move in N20 and N30: their pieces hold it.
    for (const motion_io::NcBlock& b : tip.blocks)
        if (b.name == "N20" || b.name == "N30") {
            CHECK(b.start_mm == b.end_mm);
            CHECK(b.motion == motion_io::NcMotion::Dwell);
        }
}
