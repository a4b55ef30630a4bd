// A tilted ball-end mill at a fixed orientation (3+2 work, docs/five_axis.md "Fixed tilt"): a
// straight cut along the part's +X into a flat top face, with the tool's axis leaning by a lead
// angle (toward +X) and a tilt angle (sideways), run on the bundled AC table-table machine as a
// dry-run log (app::synthesize_path_dry_run) and predicted by `predict_run` as the CLI does.
//
// The reference is a numerical integration written here from the formulas, not from the engine:
// the ball-end edge of Lee and Altintas (1996) with a constant-lead helix, psi = z tan(beta) / R,
// placed by the tool's pose in the part's frame; an edge point cuts where it lies below the top
// face and on the leading side of the tool, h = f . n > h_min (for a convex tool fed in a straight
// line the leading side is exactly the surface against uncut material), and the linear edge-force
// law acts along the edge's tangential, inward-normal and axial directions (cutter contract in
// kernels/engine_kernels.hpp: flute j at alpha = pi/2 - theta - 2 pi j / N + spin psi, M03
// clockwise seen from the spindle). The engine instead turns the stock into the tool's frame,
// removes swept volumes from dexel rays and weights elements by the material on them.
#include "app/inputs.hpp"
#include "app/path_dry_run.hpp"
#include "app/predict_run.hpp"
#include "app/workpiece_motion.hpp"
#include "app_fixtures.hpp"
#include "machine/kinematics.hpp"

#include <catch2/catch.hpp>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <optional>
#include <numbers>
#include <sstream>
#include <vector>

using namespace cutload;

namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kRadius_mm = 5, kHelix_deg = 30, kFluteLength_mm = 20;
constexpr int kFlutes = 2;
constexpr double kRpm = 8000, kFeedPerTooth_mm = 0.08;
constexpr double kDepth_mm = 2;              // tip below the top face
constexpr double kToolLength_mm = 120;
constexpr double kMinChip_mm = 5e-4;
// The top face at z = -580 in workpiece coordinates (stock z 0 with the offset below); the cut
// runs at y = -275 from x = -358 (8 mm before the stock) to -330.
constexpr double kTopZ_mm = -580, kY_mm = -275, kX0_mm = -358, kX1_mm = -330;
// Coefficients of test_coefficients() in tests/force_model/reference.hpp: every term non-zero.
constexpr double kKtc = 700, kKrc = 210, kKac = 120, kKte = 20, kKre = 28, kKae = 2;

// The block and the cut's material (test_coefficients()), with `tool_json` as the tool.
std::string spec_with_tool(const std::string& tool_json) {
    return R"json({"tool": )json" + tool_json + R"json(,
  "material": {"name": "test", "Ktc_N_mm2": 700, "Krc_N_mm2": 210, "Kac_N_mm2": 120,
               "Kte_N_mm": 20, "Kre_N_mm": 28, "Kae_N_mm": 2},
  "stock": {"box_mm": {"min": [0, -15, -20], "max": [40, 15, 0]}},
  "setup": {"offset_mm": [350, 275, 580]},
  "resolution": {"angle_step_deg": 2, "axial_step_mm": 0.1, "grid_mm": 0.1}
})json";
}
const std::string kSpec = spec_with_tool(R"json({"shape": "ball", "diameter_mm": 10, "flutes": 2, "helix_deg": 30,
  "corner_radius_mm": 5, "flute_length_mm": 20, "stickout_mm": 30, "holder": {"diameter_mm": 20, "length_mm": 40}})json");

// The tool's axis (tip to spindle) for a lead angle about the part's y (leaning toward +X, the
// feed) and a tilt angle about the feed direction (leaning toward -Y).
Eigen::Vector3d tool_axis(double lead_deg, double tilt_deg) {
    const double l = lead_deg * kPi / 180, t = tilt_deg * kPi / 180;
    return {std::sin(l), -std::cos(l) * std::sin(t), std::cos(l) * std::cos(t)};
}

struct Forces {
    double x = 0, y = 0, z = 0;
};

// The log predicted through the AC machine with the 120 mm tool length, as `cutload predict
// --machine` reads it.
app::RunInput machine_input(const std::string& log_path, const std::string& spec_json,
                            std::shared_ptr<const machine::Machine> machine,
                            force_model::Device device = force_model::Device::Cpu) {
    app::RunInput in;
    in.log_path = log_path;
    in.read = app::read_options(app::LogFormat{});
    in.spec = force_model::parse_run_spec_text(spec_json, "fixed_tilt.json");
    in.machine = std::move(machine);
    in.tool_length_mm = kToolLength_mm;
    in.device = device;
    return in;
}

// The reference: forces on the tool in workpiece axes at spindle angle theta (steady state), for
// the tool frame R (columns: the tool's x, y, z in workpiece axes) and the tip's depth below the
// top face. Midpoint rule over `steps` pieces of the ball's quarter arc and of the flank.
Forces reference_forces(const Eigen::Matrix3d& R, double theta_rad, int steps = 1500) {
    const Eigen::Vector3d f_tool = R.transpose() * Eigen::Vector3d(kFeedPerTooth_mm, 0, 0);   // per tooth
    const double lag_per_mm = std::tan(kHelix_deg * kPi / 180) / kRadius_mm;
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    // One edge element: radius r, height z above the tip, outward normal (nr, nz) in the (r, z)
    // half-plane, length db along the edge.
    const auto element = [&](double r, double z, double nr, double nz, double db) {
        for (int j = 0; j < kFlutes; ++j) {
            const double alpha = kPi / 2 - theta_rad - 2 * kPi * j / kFlutes + z * lag_per_mm;
            const double ca = std::cos(alpha), sa = std::sin(alpha);
            const Eigen::Vector3d n(nr * ca, nr * sa, nz);
            const double h = f_tool.dot(n);
            // Trailing side (h <= 0): the material there is gone; chips thinner than the minimum rub
            // and carry no force (the model's minimum chip thickness, docs/force_model.md).
            if (!(h > kMinChip_mm)) continue;
            const Eigen::Vector3d p_tool(r * ca, r * sa, z);
            const double z_w = kTopZ_mm - kDepth_mm + (R * p_tool).z();
            if (!(z_w < kTopZ_mm)) continue;   // above the top face
            const double Ft = (kKtc * h + kKte) * db, Fr = (kKrc * h + kKre) * db, Fa = (kKac * h + kKae) * db;
            const Eigen::Vector3d t(-sa, ca, 0);                  // against the cutting speed (M03)
            const Eigen::Vector3d a(-nz * ca, -nz * sa, nr);      // along the edge in the (r, z) plane
            sum += Ft * t - Fr * n + Fa * a;
        }
    };
    const double dk = (kPi / 2) / steps;
    for (int i = 0; i < steps; ++i) {
        const double k = (i + 0.5) * dk;   // from the tip (k = 0) to the equator
        element(kRadius_mm * std::sin(k), kRadius_mm * (1 - std::cos(k)), std::sin(k), -std::cos(k), kRadius_mm * dk);
    }
    const double dz = (kFluteLength_mm - kRadius_mm) / steps;
    for (int i = 0; i < steps; ++i) element(kRadius_mm, kRadius_mm + (i + 0.5) * dz, 1, 0, dz);
    const Eigen::Vector3d w = R * sum;
    return {w.x(), w.y(), w.z()};
}

// The cut's dry-run log through the AC machine, written to `dir`; the tool frame the machine
// holds it in, from forward kinematics at the log's first axes.
struct TiltLog {
    std::string path;
    app::PathDryRun run;
    Eigen::Matrix3d R;
};

TiltLog tilted_log(const std::filesystem::path& dir, double lead_deg, double tilt_deg, const machine::Machine& m) {
    app::PathDryRunSpec s;
    const Eigen::Vector3d axis = tool_axis(lead_deg, tilt_deg);
    const double feed_mm_s = kFeedPerTooth_mm * kFlutes * kRpm / 60;
    s.path = [axis, feed_mm_s](double u) {
        app::PathPose p;
        p.tip_mm = {kX0_mm + feed_mm_s * u, kY_mm, kTopZ_mm - kDepth_mm};
        p.axis = {axis.x(), axis.y(), axis.z()};
        return p;
    };
    s.duration_s = (kX1_mm - kX0_mm) / feed_mm_s;
    s.tool_length_mm = kToolLength_mm;
    s.start_axes = {{'A', 0}, {'C', 180}};
    s.spindle_rpm = kRpm;
    s.idle_before_s = 0.3;
    s.idle_after_s = 0.2;
    s.seed = 20261128;
    TiltLog log;
    std::ostringstream csv;
    log.run = app::synthesize_path_dry_run(s, m, csv);
    log.path = (dir / fmt::format("tilt_{}_{}.csv", lead_deg, tilt_deg)).string();
    apptest::write_text(log.path, csv.str());
    // The pose at the path's start, where the log stands still before the cut.
    const motion_io::MotionModel axes = motion_io::ingest(log.path, motion_io::ReadOptions{});
    machine::AxisPositions q;
    for (std::size_t k = 0; k < m.chain.size(); ++k) {
        const machine::Axis& a = m.chain[k];
        q.value[k] = !a.rotary() ? (a.name == 'X' ? axes.x_mm[0] : a.name == 'Y' ? axes.y_mm[0] : axes.z_mm[0])
                                 : axes.rot_deg[std::size_t(std::tolower(a.name) - 'a')][0];
    }
    log.R = machine::forward(m, q, kToolLength_mm, machine::ErrorMode::Nominal).tool_to_workpiece.R;
    return log;
}

struct Comparison {
    double mean_error = 0;   // |mean engine - mean reference| / |mean reference|
    double trace_rms = 0;    // RMS of the force-vector difference / peak reference resultant
    double offset_deg = 0;   // fitted phase offset of the reference against the rows' spindle angle
    double mean_N = 0;
    std::size_t rows = 0;
};

// The rows of the steady window (the tool 12 to 20 mm into the stock) against the reference at
// each row's spindle angle plus an offset fitted on a 0.25 deg grid (the spindle angle's zero is
// the log's, not a published one).
Comparison compare(const std::vector<force_model::ForceSample>& rows, const TiltLog& log) {
    const double feed_mm_s = kFeedPerTooth_mm * kFlutes * kRpm / 60;
    const double t0 = log.run.path_start_s + log.run.lag_s + 20 / feed_mm_s,
                 t1 = log.run.path_start_s + log.run.lag_s + 26 / feed_mm_s;
    // The reference is periodic in the tooth period: tabulate it on a fine grid.
    constexpr int kTable = 4 * 360;
    std::vector<Forces> table(kTable);
    for (int k = 0; k < kTable; ++k) table[std::size_t(k)] = reference_forces(log.R, 2 * kPi * k / kTable);
    const auto ref_at = [&](double deg) {
        const double u = std::fmod(std::fmod(deg, 360.0) + 360.0, 360.0) / 360.0 * kTable;
        const int k0 = int(u) % kTable, k1 = (k0 + 1) % kTable;
        const double w = u - std::floor(u);
        const Forces& a = table[std::size_t(k0)];
        const Forces& b = table[std::size_t(k1)];
        return Forces{a.x + w * (b.x - a.x), a.y + w * (b.y - a.y), a.z + w * (b.z - a.z)};
    };
    std::vector<const force_model::ForceSample*> window;
    for (const auto& r : rows)
        if (r.t_s >= t0 && r.t_s <= t1) window.push_back(&r);
    Comparison c;
    c.rows = window.size();
    if (window.empty()) return c;
    double best = 1e300;
    for (int o = 0; o < 4 * 360; ++o) {
        const double off = o * 0.25;
        double sq = 0;
        for (const auto* r : window) {
            const Forces f = ref_at(r->spindle_angle_deg + off);
            sq += std::pow(r->fx_N - f.x, 2) + std::pow(r->fy_N - f.y, 2) + std::pow(r->fz_N - f.z, 2);
        }
        if (sq < best) best = sq, c.offset_deg = off;
    }
    Forces me, mr;
    double peak = 0;
    for (const auto* r : window) {
        const Forces f = ref_at(r->spindle_angle_deg + c.offset_deg);
        me.x += r->fx_N, me.y += r->fy_N, me.z += r->fz_N;
        mr.x += f.x, mr.y += f.y, mr.z += f.z;
        peak = std::max(peak, std::sqrt(f.x * f.x + f.y * f.y + f.z * f.z));
    }
    const double n = double(window.size());
    if (std::getenv("CUTLOAD_TILT_VERBOSE"))
        fmt::print("engine mean ({:.2f}, {:.2f}, {:.2f}) N, reference ({:.2f}, {:.2f}, {:.2f}) N\n", me.x / n, me.y / n,
                   me.z / n, mr.x / n, mr.y / n, mr.z / n);
    const double diff = std::sqrt(std::pow(me.x - mr.x, 2) + std::pow(me.y - mr.y, 2) + std::pow(me.z - mr.z, 2)) / n;
    c.mean_N = std::sqrt(mr.x * mr.x + mr.y * mr.y + mr.z * mr.z) / n;
    c.mean_error = diff / c.mean_N;
    c.trace_rms = std::sqrt(best / n) / peak;
    return c;
}

std::vector<force_model::Device> devices() {
    std::vector<force_model::Device> d{force_model::Device::Cpu};
    try {
        force_model::opencl_device_name();
        d.push_back(force_model::Device::OpenCL);
    } catch (const std::exception& e) {
        WARN("no OpenCL device (" << e.what() << "): the OpenCL run is skipped");
    }
    return d;
}

}  // namespace

TEST_CASE("fixed tilt: a ball-end mill leaning 0 to 30 deg matches the numerical integration of the ball-end model",
          "[five_axis][fixed_tilt][physics]") {
    const auto machine = app::load_machine_definition(apptest::source_path("data/machines/ac_table_table.json"));
    apptest::Scratch dir("fixed_tilt");
    const auto [lead_deg, tilt_deg] = GENERATE(std::pair{0.0, 0.0}, std::pair{30.0, 0.0}, std::pair{0.0, 30.0},
                                               std::pair{15.0, 20.0}, std::pair{-20.0, -10.0});
    INFO("lead " << lead_deg << " deg, tilt " << tilt_deg << " deg");
    const TiltLog log = tilted_log(dir, lead_deg, tilt_deg, *machine);
    // The machine holds the tool at the asked axis.
    CHECK((log.R.col(2) - tool_axis(lead_deg, tilt_deg)).norm() < 1e-4);

    std::vector<std::vector<force_model::ForceSample>> by_device;
    for (const force_model::Device d : devices()) {
        app::RunInput in = machine_input(log.path, kSpec, machine, d);
        const app::RunResult r = app::predict_run(in);
        CHECK(r.tool_lean_deg == Approx(std::acos(tool_axis(lead_deg, tilt_deg).z()) * 180 / kPi).margin(1e-3));
        // The motion comes back in the part's axes: the tip on the path's line.
        const std::size_t mid = r.motion.size() / 2;
        CHECK(r.motion.y_mm[mid] == Approx(kY_mm).margin(0.01));
        CHECK(r.motion.z_mm[mid] == Approx(kTopZ_mm - kDepth_mm).margin(0.01));
        const Comparison c = compare(r.prediction.samples, log);
        INFO("mean " << c.mean_N << " N, mean error " << c.mean_error * 100 << " %, trace RMS " << c.trace_rms * 100
                     << " % of peak, offset " << c.offset_deg << " deg, rows " << c.rows);
        REQUIRE(c.rows > 5000);
        // The spindle angle's zero is as the cutter contract says (flute 0 on the tool's +Y at 0):
        // the fitted phase is a whole tooth pitch (180 deg for two flutes) within the angle step.
        const double off = std::fmod(c.offset_deg, 180.0);
        CHECK(std::min(off, 180 - off) <= 2.0);
        CHECK(c.mean_N > 50);
        // Each cutting row says where the tool stood: the asked axis, worked out by hand above
        // (FORCES.csv's tool_axis_x, tool_axis_y, tool_axis_z).
        std::size_t cutting = 0;
        double worst_axis = 0;
        for (const force_model::ForceSample& s : r.prediction.samples) {
            if (std::hypot(s.fx_N, s.fy_N, s.fz_N) < 1) continue;
            ++cutting;
            worst_axis = std::max(worst_axis, (Eigen::Vector3d(s.tool_axis_x, s.tool_axis_y, s.tool_axis_z) -
                                               tool_axis(lead_deg, tilt_deg)).norm());
        }
        CHECK(cutting > 5000);
        CHECK(worst_axis < 1e-4);
        // On a table-table machine the spindle stands on the bed's Z, so R_bed^T a = +Z and the
        // machine-axis Fz is the workpiece force along the tool axis, for every row (air too): the
        // axis and the machine-axis forces, computed apart, agree.
        double worst_fz = 0;
        for (const force_model::ForceSample& s : r.prediction.samples) {
            const double along = s.fx_N * s.tool_axis_x + s.fy_N * s.tool_axis_y + s.fz_N * s.tool_axis_z;
            worst_fz = std::max(worst_fz, std::abs(s.fz_machine_N - along) / (1 + std::hypot(s.fx_N, s.fy_N, s.fz_N)));
        }
        CHECK(worst_fz < 1e-5);
        // Issue 15 asks for the traces within 3 %; measured: mean 0.01 to 0.22 %, trace RMS 0.46 to
        // 0.75 % of the peak (the grid's 0.1 mm cells against the turned top face), so the test
        // holds the engine to tighter bounds than that.
        CHECK(c.mean_error < 0.01);
        CHECK(c.trace_rms < 0.015);
        by_device.push_back(r.prediction.samples);
    }
    if (by_device.size() == 2) {
        // OpenCL against the scalar twins (as tests/force_model/test_engine_predict.cpp compares
        // them): the RMS of the rows' force difference within 0.5 % of the RMS force.
        const auto& a = by_device[0];
        const auto& b = by_device[1];
        REQUIRE(a.size() == b.size());
        double diff = 0, norm = 0;
        for (std::size_t i = 0; i < a.size(); ++i) {
            diff += std::pow(a[i].fx_N - b[i].fx_N, 2) + std::pow(a[i].fy_N - b[i].fy_N, 2) + std::pow(a[i].fz_N - b[i].fz_N, 2);
            norm += std::pow(a[i].fx_N, 2) + std::pow(a[i].fy_N, 2) + std::pow(a[i].fz_N, 2);
        }
        REQUIRE(norm > 0);
        INFO("OpenCL against the twins: RMS difference " << std::sqrt(diff / norm) * 100 << " % of the RMS force");
        CHECK(std::sqrt(diff / norm) < 0.005);
    }
}

namespace {

// Machine axes sample by sample (1 ms) from a function of time: x, y, z in mm, A and C in deg.
struct Axes {
    double x, y, z, a, c;
};
template <class F>
motion_io::MotionModel axes_log(double duration_s, F at) {
    motion_io::MotionModel m;
    m.step_s = 0.001;
    m.block_names = {"N10"};
    const auto n = std::size_t(std::lround(duration_s / m.step_s)) + 1;
    for (std::size_t i = 0; i < n; ++i) {
        const double t = double(i) * m.step_s;
        const Axes p = at(t), q = at(t + 1e-4), o = at(t - 1e-4);
        m.t_s.push_back(t);
        m.x_mm.push_back(p.x), m.y_mm.push_back(p.y), m.z_mm.push_back(p.z);
        m.vx_mm_s.push_back((q.x - o.x) / 2e-4), m.vy_mm_s.push_back((q.y - o.y) / 2e-4), m.vz_mm_s.push_back((q.z - o.z) / 2e-4);
        m.spindle_rpm.push_back(8000);
        m.spindle_angle_deg.push_back(48000 * t);
        m.block.push_back(0);
        m.rot_deg[0].push_back(p.a), m.rot_vel_deg_s[0].push_back((q.a - o.a) / 2e-4);
        m.rot_deg[2].push_back(p.c), m.rot_vel_deg_s[2].push_back((q.c - o.c) / 2e-4);
    }
    m.session_start = {0};
    return m;
}

Eigen::Vector3d tip_at(const machine::Machine& m, const Axes& p) {
    const machine::AxisPositions q = machine::positions(m, {{'X', p.x}, {'Y', p.y}, {'Z', p.z}, {'A', p.a}, {'C', p.c}});
    return machine::forward(m, q, kToolLength_mm, machine::ErrorMode::Nominal).tip_mm();
}

}  // namespace

TEST_CASE("fixed tilt: a tilted run with its NC program predicts the commanded path in the tool's frame too, and compares "
          "the blocks",
          "[five_axis][fixed_tilt][program]") {
    const auto machine = app::load_machine_definition(apptest::source_path("data/machines/ac_table_table.json"));
    apptest::Scratch dir("fixed_tilt_program");
    const TiltLog log = tilted_log(dir, 15, 20, *machine);
    app::RunInput in = machine_input(log.path, kSpec, machine);
    app::ProgramSource program;
    program.text = log.run.program;   // the machine-axis program the log is a dry run of (G93 pieces)
    program.name = "tilt.nc";
    program.settings.work_offsets_mm["G54"] = {0, 0, 0};
    in.program = program;
    const app::RunResult r = app::predict_run(in);
    CHECK(r.fixed_tilt);
    REQUIRE(r.commanded);
    // The actual prediction is the one without the program.
    const Comparison actual = compare(r.prediction.samples, log);
    CHECK(actual.mean_error < 0.01);
    // The commanded rows, put on the log's time axis by the run's own warp, against the same
    // numerical integration: the program is the path the log followed, without the servo lag.
    std::vector<force_model::ForceSample> commanded = r.commanded->commanded.samples;
    for (force_model::ForceSample& s : commanded) s.t_s = r.commanded->to_actual_time(s.t_s);
    const Comparison c = compare(commanded, log);
    INFO("commanded: mean " << c.mean_N << " N, mean error " << c.mean_error * 100 << " %, trace RMS " << c.trace_rms * 100
                            << " % of peak, rows " << c.rows);
    REQUIRE(c.rows > 5000);
    CHECK(c.mean_N > 50);
    CHECK(c.mean_error < 0.01);
    CHECK(c.trace_rms < 0.015);
    // The path's block, compared: matched on the path (stock axes both), peaks alike.
    const auto& blocks = r.commanded->blocks;
    const auto path = std::find_if(blocks.begin(), blocks.end(), [&](const auto& b) { return b.block == log.run.block; });
    REQUIRE(path != blocks.end());
    INFO("N30: actual peak " << path->actual_peak_force_N << " N, commanded " << path->commanded_peak_force_N
                             << " N, deviation " << path->max_deviation_mm << " mm");
    CHECK(path->commanded_peak_force_N > 100);
    CHECK(std::abs(path->force_difference_pct) < 3);
    CHECK(path->max_deviation_mm < 0.05);

    // A program that turns the tool where it can reach the stock is refused naming its line and
    // block: here A turns 10 deg more at the cut's end, the tool still in the stock.
    std::string turned = log.run.program;
    const std::size_t last = turned.rfind("N30 G93");
    REQUIRE(last != std::string::npos);
    const std::size_t a_at = turned.find(" A", last);
    const double a_deg = std::stod(turned.substr(a_at + 2));
    const std::size_t end = turned.find('\n', last);
    const int line = int(std::count(turned.begin(), turned.begin() + std::ptrdiff_t(end), '\n')) + 2;
    turned.insert(end + 1, fmt::format("N35 G94 G01 A{:.3f} F1000\n", a_deg + 10));
    // The run with `text` as its program is refused at `line`, naming `block`.
    const auto refused_at = [&](const std::string& text, int at, const std::string& block) {
        in.program->text = text;
        try {
            app::predict_run(in);
            FAIL("block " << block << " was not refused");
        } catch (const std::exception& e) {
            CHECK_THAT(e.what(), Catch::Contains(fmt::format("tilt.nc:{}: block {}: where the tool can reach the stock "
                                                             "its axis turns",
                                                             at, block)));
        }
    };
    refused_at(turned, line, "N35");
    // After the cut: up and clear, A back to 0 in the air (allowed), then a rapid with the tool
    // vertical straight through the part from 250 mm on one side to 250 mm on the other: both
    // ends out of reach, the middle in the stock. Refused at that block's line.
    std::string crossing = log.run.program;
    const std::size_t after = crossing.find('\n', crossing.rfind("N30 G")) + 1;
    const int crossing_line = int(std::count(crossing.begin(), crossing.begin() + std::ptrdiff_t(after), '\n')) + 5;
    crossing.insert(after, "N36 G94 G00 Z-200.\nN37 A0.\nN38 X-600. Y-275.\nN39 Z-465.\nN40 X-100.\n");
    refused_at(crossing, crossing_line, "N40");
}

TEST_CASE("fixed tilt: the tool may index in the air, turning where it can reach the stock is refused, naming when and "
          "how far",
          "[five_axis][fixed_tilt][errors]") {
    const auto machine = app::load_machine_definition(apptest::source_path("data/machines/ac_table_table.json"));
    // Home at A = C = 0 high above the table, A indexes to -20 deg and C to 90 deg in the air over
    // 0.2 s, then Z comes down 150 mm and X feeds; with `c_turn_deg`, C turns by that much more
    // while X feeds.
    const auto log = [&](double c_turn_deg) {
        return axes_log(1.0, [c_turn_deg](double t) {
            const double index = std::clamp((t - 0.1) / 0.2, 0.0, 1.0);
            const double down = 150 * std::clamp((t - 0.35) / 0.15, 0.0, 1.0);
            const double feed = std::clamp(t - 0.5, 0.0, 0.5);
            return Axes{-330 + 20 * feed, -275, -150 - down, -20 * index, 90 * index + c_turn_deg * feed / 0.5};
        });
    };
    // A stock box around where the tip feeds (stock = workpiece coordinates here), 5 mm deep.
    const Eigen::Vector3d cut0 = tip_at(*machine, {-330, -275, -300, -20, 90}), cut1 = tip_at(*machine, {-320, -275, -300, -20, 90});
    app::ToolReach reach;
    for (int k = 0; k < 3; ++k) {
        reach.stock_box.min_mm[k] = std::min(cut0[k], cut1[k]) - 10;
        reach.stock_box.max_mm[k] = std::max(cut0[k], cut1[k]) + 10;
    }
    reach.stock_box.max_mm[2] = std::max(cut0.z(), cut1.z()) + 5;
    reach.radius_mm = 10;
    // Where the tool stands at home it is far above the box: the index is in the air.
    const Eigen::Vector3d home = tip_at(*machine, {-330, -275, -150, 0, 0});
    REQUIRE(home.z() > reach.stock_box.max_mm[2] + kToolLength_mm);

    const app::ToolFrame f = app::tool_frame(log(0), *machine, kToolLength_mm, reach);
    CHECK(f.tilted);
    CHECK(f.lean_deg == Approx(20).margin(1e-9));
    CHECK(f.t_s > 0.35);   // the first sample that can reach the box is on the way down
    CHECK(f.t_s < 0.5);
    // The motion in the tool's frame: the feed along the part's turned X, at the log's 20 mm/s.
    const motion_io::MotionModel axes = log(0);
    const motion_io::MotionModel w = app::workpiece_motion(axes, *machine, kToolLength_mm, f);
    const std::size_t i = 750;
    CHECK(std::hypot(w.vx_mm_s[i], w.vy_mm_s[i], w.vz_mm_s[i]) == Approx(20).epsilon(1e-6));
    const Eigen::Vector3d tip_tool = f.tool_to_workpiece.transpose() * tip_at(*machine, {-330 + 20 * 0.25, -275, -300, -20, 90});
    CHECK(w.x_mm[i] == Approx(tip_tool.x()).margin(1e-6));
    CHECK(w.y_mm[i] == Approx(tip_tool.y()).margin(1e-6));
    CHECK(w.z_mm[i] == Approx(tip_tool.z()).margin(1e-6));
    // Where the tool stands at the cutting orientation, the cutter's angle against the part is the
    // spindle's (the tool's frame is the cutting frame): the index's turn, about no fixed axis,
    // does not shift it, nor the speed.
    for (std::size_t k = 350; k < w.size(); k += 50) {
        INFO("t = " << w.t_s[k]);
        CHECK(w.spindle_angle_deg[k] == Approx(axes.spindle_angle_deg[k]).margin(1e-9));
        CHECK(w.spindle_rpm[k] == Approx(8000).margin(1e-9));
    }

    // C turning 2 deg while it feeds: simultaneous five-axis work, refused.
    try {
        app::tool_frame(log(2), *machine, kToolLength_mm, reach);
        FAIL("a tilted tool turning in the stock was taken");
    } catch (const app::WorkpieceMotionError& e) {
        CHECK_THAT(e.what(), Catch::Contains("the tool axis turns") && Catch::Contains("leaning 20 deg") &&
                                 Catch::Contains("(at most 2 deg, at t = 1.0000 s)") &&
                                 Catch::Contains("multi-direction stock"));
    }
    // The same turn far from the stock is no matter.
    app::ToolReach far = reach;
    for (int k = 0; k < 3; ++k) far.stock_box.min_mm[k] += 1000, far.stock_box.max_mm[k] += 1000;
    CHECK_NOTHROW(app::tool_frame(log(2), *machine, kToolLength_mm, far));
}

TEST_CASE("fixed tilt: a run starts from a tilted run's stock at the same tilt, and is refused another stock",
          "[five_axis][fixed_tilt][stock]") {
    const auto machine = app::load_machine_definition(apptest::source_path("data/machines/ac_table_table.json"));
    apptest::Scratch dir("fixed_tilt_base");
    const TiltLog log = tilted_log(dir, 20, 10, *machine);
    app::RunInput in = machine_input(log.path, kSpec, machine);
    const app::RunResult first = app::predict_run(in);
    REQUIRE(first.prediction.final_stock);
    double first_mm3 = 0;
    for (const auto& b : first.prediction.blocks) first_mm3 += b.removed_mm3;
    CHECK(first_mm3 > 100);
    // The stock keeps its frame through the bytes the service stores.
    const auto stored = force_model::load_stock_bytes(force_model::save_stock_bytes(*first.prediction.final_stock), "run 1");
    CHECK(force_model::stock_grid_frame(*stored).m == force_model::stock_grid_frame(*first.prediction.final_stock).m);

    // The same cut again on what the first left: nothing left to cut along the way (where the first
    // run stopped in the material, the tool comes to rest against what it left there).
    in.base_stock = stored.get();
    const app::RunResult again = app::predict_run(in);
    double again_mm3 = 0;
    for (const auto& b : again.prediction.blocks) again_mm3 += b.removed_mm3;
    const double feed_mm_s = kFeedPerTooth_mm * kFlutes * kRpm / 60;
    const double t0 = log.run.path_start_s + log.run.lag_s + 10 / feed_mm_s, t1 = log.run.path_start_s + log.run.lag_s + 24 / feed_mm_s;
    struct Load {
        double mean_N = 0, peak_N = 0;
    };
    const auto load_in = [&](const std::vector<force_model::ForceSample>& rows) {
        Load l;
        std::size_t n = 0;
        for (const auto& r : rows)
            if (r.t_s >= t0 && r.t_s <= t1) {
                const double f = std::hypot(r.fx_N, r.fy_N, r.fz_N);
                l.mean_N += f, l.peak_N = std::max(l.peak_N, f), ++n;
            }
        l.mean_N /= double(std::max<std::size_t>(n, 1));
        return l;
    };
    const Load l1 = load_in(first.prediction.samples), l2 = load_in(again.prediction.samples);
    INFO("again: " << again_mm3 << " mm3; mean " << l2.mean_N << " N, peak " << l2.peak_N << " N against " << l1.mean_N
                   << " N, " << l1.peak_N << " N");
    CHECK(again_mm3 < 0.01 * first_mm3);
    REQUIRE(l1.mean_N > 100);
    // What is left are slivers where the ball's surface lies on the rays' samples of its own sweep:
    // the sub-cell walls that bring a flat end mill's re-cut under 1 % (tests/force_model/
    // test_engine_recut.cpp) model cylindrical flanks only, not a ball's curved groove. Measured
    // here: mean 4.5 %, peak 9.6 % of the first cut; the same cut with the tool vertical leaves
    // 4.5 % and 24 %, so the tilt adds nothing to it.
    CHECK(l2.mean_N < 0.06 * l1.mean_N);
    CHECK(l2.peak_N < 0.15 * l1.peak_N);

    // A stock in stock axes (a vertical tool's) cannot carry a tilted run, nor the other way round.
    const auto plain = force_model::make_stock(in.spec.stock, in.spec.resolution.grid_mm);
    in.base_stock = plain.get();
    try {
        app::predict_run(in);
        FAIL("a tilted run started from a stock in stock axes");
    } catch (const app::InputError& e) {
        CHECK(e.key() == "base_stock");
        CHECK_THAT(e.what(), Catch::Contains("leaning 0 deg") && Catch::Contains("leans 22.") &&
                                 Catch::Contains("same orientation"));
    }
    // And the tilted run's stock under a run with the tool vertical.
    const TiltLog vertical = tilted_log(dir, 0, 0, *machine);
    in.log_path = vertical.path;
    in.base_stock = stored.get();
    try {
        app::predict_run(in);
        FAIL("a vertical run started from a tilted run's stock");
    } catch (const app::InputError& e) {
        CHECK(e.key() == "base_stock");
        CHECK_THAT(e.what(), Catch::Contains("leaning 22.") && Catch::Contains("leans 0 deg"));
    }
}

namespace {

// A full-immersion slot, 2 mm deep, with a flat D8 end mill: along +X into the top face with the
// tool vertical, along +X into the -Y face with the tool horizontal (A turned -90 deg on the AC
// machine), and along +Y into the +X face (A -90 deg, C 90 deg). The same cut turned, so in the
// tool's frame the forces must be the same, and all must be Altintas's closed-form slot averages
// (issue 15's invariance: a cut through the AC chain with the table turned and A tilted gives the
// three-axis forces, turned).
const std::string kSlotSpec = spec_with_tool(R"json({"shape": "flat", "diameter_mm": 8, "flutes": 2, "helix_deg": 30,
  "corner_radius_mm": 0, "flute_length_mm": 20, "stickout_mm": 30, "holder": {"diameter_mm": 20, "length_mm": 40}})json");
constexpr double kSlotDepth_mm = 2, kSlotDiameter_mm = 8, kSlotFeed_mm = 0.05;

// Altintas (2012, ch. 2): over a full slot (immersion 0 to pi), with h = c sin(phi) and the
// tool-force convention Fx = -Ft cos - Fr sin, Fy = Ft sin - Fr cos, Fz = Fa (feed along +x),
// the integrals over phi are -Krc c pi/2 - 2 Kre, Ktc c pi/2 + 2 Kte and 2 Kac c + pi Kae; the
// average multiplies them by N a / (2 pi).
Eigen::Vector3d slot_average_N() {
    const double c = kSlotFeed_mm, a = kSlotDepth_mm, k = kFlutes * a / (2 * kPi);
    return {k * (-kKrc * c * kPi / 2 - 2 * kKre), k * (kKtc * c * kPi / 2 + 2 * kKte), k * (2 * kKac * c + kPi * kKae)};
}

}  // namespace

TEST_CASE("fixed tilt: a slot cut by a horizontal tool in a side face is the vertical tool's slot turned, and the closed "
          "form",
          "[five_axis][fixed_tilt][physics]") {
    const auto machine = app::load_machine_definition(apptest::source_path("data/machines/ac_table_table.json"));
    apptest::Scratch dir("fixed_tilt_slot");
    // The slot's start (8 mm before the stock), feed direction and the tool's axis in workpiece
    // coordinates (the stock box spans x -350..-310, y -290..-260, z -600..-580 there).
    struct Slot {
        const char* name;
        Eigen::Vector3d start, feed, axis;
        double a_deg, c_deg;   // where the machine's inverse kinematics starts
    };
    const Slot slot = GENERATE(Slot{"vertical tool, top face", {kX0_mm, kY_mm, kTopZ_mm - kSlotDepth_mm}, {1, 0, 0}, {0, 0, 1}, 0, 0},
                               Slot{"horizontal tool, -Y face", {kX0_mm, -290 + kSlotDepth_mm, -590}, {1, 0, 0}, {0, -1, 0}, -90, 0},
                               Slot{"horizontal tool, +X face (C turned)", {-310 - kSlotDepth_mm, -298, -590}, {0, 1, 0}, {1, 0, 0},
                                    -90, 90});
    const bool horizontal = slot.axis.z() < 0.5;
    INFO(slot.name);
    const double feed_mm_s = kSlotFeed_mm * kFlutes * kRpm / 60;
    app::PathDryRunSpec s;
    s.path = [&](double u) {
        app::PathPose p;
        const Eigen::Vector3d tip = slot.start + feed_mm_s * u * slot.feed;
        p.tip_mm = {tip.x(), tip.y(), tip.z()};
        p.axis = {slot.axis.x(), slot.axis.y(), slot.axis.z()};
        return p;
    };
    s.duration_s = (kX1_mm - kX0_mm) / feed_mm_s;
    s.tool_length_mm = kToolLength_mm;
    s.start_axes = {{'A', slot.a_deg}, {'C', slot.c_deg}};
    s.spindle_rpm = kRpm;
    s.idle_before_s = 0.3;
    s.idle_after_s = 0.2;
    s.seed = 20261129;
    std::ostringstream csv;
    const app::PathDryRun run = app::synthesize_path_dry_run(s, *machine, csv);
    const std::string path = (dir / "slot.csv").string();
    apptest::write_text(path, csv.str());

    for (const force_model::Device d : devices()) {
        app::RunInput in = machine_input(path, kSlotSpec, machine, d);
        const app::RunResult r = app::predict_run(in);
        CHECK(r.tool_lean_deg == Approx(horizontal ? 90 : 0).margin(1e-6));
        // The tool's frame: its axis and the feed's direction in it (the tool's x and y are the
        // machine's, so they are read from the result, not assumed).
        const Eigen::Vector3d z_t(r.tool_axis[0], r.tool_axis[1], r.tool_axis[2]);
        const Eigen::Vector3d x_t = slot.feed;   // the feed is across the axis in every set-up
        const Eigen::Vector3d y_t = z_t.cross(x_t);
        // Over the tip 12 to 18 mm into the stock, a whole number of tooth periods.
        const double t0 = run.path_start_s + run.lag_s + 20 / feed_mm_s;
        const double tooth_s = 60 / (kRpm * kFlutes), t1 = t0 + std::floor(6 / feed_mm_s / tooth_s + 0.5) * tooth_s;
        const double steady_mm = (t1 - t0) * feed_mm_s;
        Eigen::Vector3d mean = Eigen::Vector3d::Zero();
        double removed_mm3 = 0;
        std::size_t n = 0;
        double last_angle = 0;
        for (const auto& row : r.prediction.samples) {
            if (row.t_s < t0 || row.t_s > t1) continue;
            // Rows come every 2 deg of spindle angle, plus one per motion sample: weight each by the
            // angle it covers so the extra rows do not bias the mean.
            const double w = n == 0 ? 0 : row.spindle_angle_deg - last_angle;
            last_angle = row.spindle_angle_deg;
            const Eigen::Vector3d f(row.fx_N, row.fy_N, row.fz_N);
            mean += w * Eigen::Vector3d(f.dot(x_t), f.dot(y_t), f.dot(z_t));
            removed_mm3 += row.removed_mm3;
            ++n;
        }
        REQUIRE(n > 1000);
        double covered_deg = 0;
        {
            double first = -1;
            for (const auto& row : r.prediction.samples)
                if (row.t_s >= t0 && row.t_s <= t1) {
                    if (first < 0) first = row.spindle_angle_deg;
                    covered_deg = row.spindle_angle_deg - first;
                }
        }
        mean /= covered_deg;
        const Eigen::Vector3d expected = slot_average_N();
        INFO((d == force_model::Device::Cpu ? "cpu" : "opencl") << ": tool frame mean (" << mean.x() << ", " << mean.y()
             << ", " << mean.z() << ") N, closed form (" << expected.x() << ", " << expected.y() << ", " << expected.z()
             << ") N; removed " << removed_mm3 / steady_mm << " mm3/mm");
        CHECK((mean - expected).norm() < 0.01 * expected.norm());
        // The slot's section, D x depth, per mm of path (the rows' removed volume lags the tool
        // by the stock lag, so over steady path it is as much slot).
        CHECK(removed_mm3 / steady_mm == Approx(kSlotDiameter_mm * kSlotDepth_mm).epsilon(0.005));
    }
}

TEST_CASE("fixed tilt: the holder of a horizontal tool is checked against the side face it cuts: clear, near miss, contact",
          "[five_axis][fixed_tilt][holder]") {
    // A flat D8 end mill with 35 mm of flutes, its holder (D20) 40 mm from the tip, slots along +X
    // into the block's -Y face with A turned -90 deg, `depth` mm deep along the tool's axis
    // (through the 30 mm block beyond 30). The holder's face then stands 40 - depth mm off the face
    // it cut into, parallel to it: that is the clearance (document 004's shell, 10 mm here).
    const auto machine = app::load_machine_definition(apptest::source_path("data/machines/ac_table_table.json"));
    apptest::Scratch dir("fixed_tilt_holder");
    const double depth_mm = GENERATE(2.0, 33.0, 42.0);
    INFO("depth " << depth_mm << " mm");
    const double feed_mm_s = kSlotFeed_mm * kFlutes * kRpm / 60;
    app::PathDryRunSpec s;
    s.path = [&](double u) {
        app::PathPose p;
        p.tip_mm = {kX0_mm + feed_mm_s * u, -290 + depth_mm, -590};
        p.axis = {0, -1, 0};
        return p;
    };
    s.duration_s = 16 / feed_mm_s;   // 8 mm into the block
    s.tool_length_mm = kToolLength_mm;
    s.start_axes = {{'A', -90}, {'C', 0}};
    s.spindle_rpm = kRpm;
    s.idle_before_s = 0.2;
    s.idle_after_s = 0.1;
    std::ostringstream csv;
    app::synthesize_path_dry_run(s, *machine, csv);
    const std::string path = (dir / "holder.csv").string();
    apptest::write_text(path, csv.str());
    std::string spec = kSlotSpec;
    const auto replace = [&](const std::string& from, const std::string& to) {
        const std::size_t at = spec.find(from);
        REQUIRE(at != std::string::npos);
        spec.replace(at, from.size(), to);
    };
    replace(R"("flute_length_mm": 20, "stickout_mm": 30)", R"("flute_length_mm": 35, "stickout_mm": 40)");
    replace(R"("resolution")", R"("limits": {"holder_clearance_mm": 10}, "resolution")");
    for (const force_model::Device d : devices()) {
        app::RunInput in = machine_input(path, spec, machine, d);
        const app::RunResult r = app::predict_run(in);
        REQUIRE(r.fixed_tilt);
        std::optional<double> near_mm;
        bool contact = false;
        for (const auto& b : r.prediction.blocks)
            for (const auto& f : b.flags) {
                if (f.flag == "holder_near_miss") near_mm = std::min(near_mm.value_or(1e9), f.value);
                contact = contact || f.flag == "holder_contact";
            }
        INFO((d == force_model::Device::Cpu ? "cpu" : "opencl") << ": near miss " << near_mm.value_or(-1) << " mm, contact "
                                                                << contact);
        if (depth_mm < 30 - 10) {
            CHECK(!near_mm);
            CHECK(!contact);
        } else if (depth_mm < 40) {
            CHECK(!contact);
            REQUIRE(near_mm);
            CHECK(*near_mm == Approx(40 - depth_mm).margin(0.15));
        } else {
            CHECK(contact);
        }
    }
}

TEST_CASE("fixed tilt: the upload's streamed read finds the job's orientation, and both refuse a turned box past the "
          "cell limit with the same figures",
          "[five_axis][fixed_tilt][work]") {
    const auto machine = app::load_machine_definition(apptest::source_path("data/machines/ac_table_table.json"));
    apptest::Scratch dir("fixed_tilt_work");
    const TiltLog log = tilted_log(dir, 30, 10, *machine);
    app::RunInput in = machine_input(log.path, kSpec, machine);
    const app::InspectedLog seen = app::inspect_run_log(in.log_path, in.read, in.spec, machine.get(), in.tool_length_mm);
    REQUIRE(seen.orientation.tilted);
    CHECK(seen.orientation.lean_deg == Approx(std::acos(tool_axis(30, 10).z()) * 180 / kPi).margin(1e-3));
    // The 40 x 30 x 20 mm box at 0.1 mm is 120 000 cells; turned into the tool's frame, more.
    const double flat_cells = force_model::stock_cells(in.spec.stock, in.spec.resolution.grid_mm);
    const app::WorkEstimate upload = app::estimate_run_work(seen.report, in.spec, seen.orientation);
    CHECK(flat_cells == Approx(120000));
    CHECK(upload.stock_cells > flat_cells * 1.2);

    SECTION("a limit between the box and the turned box: refused at upload with the job's message") {
        in.limits.max_stock_cells = (flat_cells + upload.stock_cells) / 2;
        // As the upload estimated before it knew the orientation: the unturned box passed.
        CHECK_NOTHROW(app::check_run_work(app::estimate_run_work(seen.report, in.spec, {}), in.limits, {}));
        std::string at_upload, in_job;
        try {
            app::check_run_work(upload, in.limits, seen.orientation);
        } catch (const app::TooMuchWork& e) {
            at_upload = e.what();
        }
        try {
            app::predict_run(in);
        } catch (const app::TooMuchWork& e) {
            in_job = e.what();
        }
        CHECK_THAT(at_upload, Catch::StartsWith("stock_cells: resolution.grid_mm gives the stock box") &&
                                  Catch::Contains("(the box turned into the frame of the tool leaning 31."));
        CHECK(at_upload == in_job);
    }
    SECTION("a limit the turned box fits: both pass, the job at the orientation and the cells the upload found") {
        in.limits.max_stock_cells = upload.stock_cells;
        CHECK_NOTHROW(app::check_run_work(upload, in.limits, seen.orientation));
        const app::RunResult r = app::predict_run(in);
        CHECK(r.fixed_tilt);
        CHECK(r.work.stock_cells == upload.stock_cells);
        CHECK(r.tool_lean_deg == seen.orientation.lean_deg);
        const Eigen::Matrix3d R = app::tool_to_workpiece(seen.orientation.grid_from_stock);
        for (int k = 0; k < 3; ++k) CHECK(r.tool_axis[std::size_t(k)] == R(k, 2));
    }
}
