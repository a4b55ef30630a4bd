// A tool that turns while it cuts (simultaneous five-axis work, docs/five_axis.md section 3.4),
// through the whole chain as `cutload predict --machine` runs it: a dry-run log of the bundled AC
// table-table machine, its rotary axes turned into poses and twists, the pose engine on the
// multi-direction stock, rows in workpiece and machine axes.
//
// The cut: a ball end mill (D10) whose centre runs straight along the part's +X, 3 mm above a flat
// top face (the ball 2 mm deep), while its lead angle turns from 5 to 25 deg (a tilt of 10 deg
// held). Turning about its ball's centre, the tool sweeps the same groove at any lean, and the
// ball's points move with the centre's velocity plus omega x (p - c), which is tangential to the
// ball: the chip is the centre's feed along the normal, whatever the turn. The shank stays above
// the face up to a lean of asin(3/5) = 36.9 deg. So the steady forces at each instant are the
// ball's at that instant's orientation cutting a flat face, the numerical integration below,
// written from the formulas (the ball-end edge with a constant-lead helix, as
// tests/app/test_fixed_tilt.cpp's), not from the engine.
#include "app/inputs.hpp"
#include "app/path_dry_run.hpp"
#include "app/predict_run.hpp"
#include "app_fixtures.hpp"
#include "force_model/engine_fixtures.hpp"
#include "machine/kinematics.hpp"

#include <catch2/catch.hpp>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <map>
#include <memory>
#include <numbers>
#include <sstream>
#include <string>
#include <vector>

using namespace cutload;

namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kRadius_mm = 5, kHelix_deg = 30;
constexpr int kFlutes = 2;
constexpr double kRpm = 8000, kFeedPerTooth_mm = 0.08, kMinChip_mm = 5e-4;
constexpr double kToolLength_mm = 120;
// Workpiece coordinates: the top face at z = -580, the centre 3 mm above it, at y = -275, from
// x = -358 (8 mm before the stock) to -318 (32 mm into it).
constexpr double kTopZ_mm = -580, kCentreZ_mm = kTopZ_mm + 3, kY_mm = -275, kX0_mm = -358, kX1_mm = -318;
constexpr double kKtc = 700, kKrc = 210, kKac = 120, kKte = 20, kKre = 28, kKae = 2;
constexpr double kTilt_deg = 10, kLead0_deg = 5, kLead1_deg = 25;

const std::string kSpec = R"json({"tool": {"shape": "ball", "diameter_mm": 10, "flutes": 2, "helix_deg": 30,
  "corner_radius_mm": 5, "flute_length_mm": 20, "stickout_mm": 30, "holder": {"diameter_mm": 20, "length_mm": 40}},
  "material": {"name": "test", "Ktc_N_mm2": 700, "Krc_N_mm2": 210, "Kac_N_mm2": 120,
               "Kte_N_mm": 20, "Kre_N_mm": 28, "Kae_N_mm": 2},
  "stock": {"box_mm": {"min": [0, -15, -20], "max": [40, 15, 0]}},
  "setup": {"offset_mm": [350, 275, 580]},
  "resolution": {"angle_step_deg": 2, "axial_step_mm": 0.1, "grid_mm": 0.1}
})json";

Eigen::Vector3d tool_axis(double lead_deg, double tilt_deg) {
    const double l = lead_deg * kPi / 180, t = tilt_deg * kPi / 180;
    return {std::sin(l), -std::cos(l) * std::sin(t), std::cos(l) * std::cos(t)};
}

// Forces on the tool in workpiece axes at spindle angle theta for the tool frame R (columns: the
// tool's x, y, z in workpiece axes), the ball's centre kCentreZ_mm high, fed along +X. Midpoint rule
// over `steps` pieces of the ball's quarter arc.
Eigen::Vector3d reference_forces(const Eigen::Matrix3d& R, double theta_rad, int steps = 1500) {
    const Eigen::Vector3d f_tool = R.transpose() * Eigen::Vector3d(kFeedPerTooth_mm, 0, 0);
    const double lag_per_mm = std::tan(kHelix_deg * kPi / 180) / kRadius_mm;
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    const double dk = (kPi / 2) / steps;
    for (int i = 0; i < steps; ++i) {
        const double k = (i + 0.5) * dk;
        const double r = kRadius_mm * std::sin(k), z = kRadius_mm * (1 - std::cos(k));
        const double nr = std::sin(k), nz = -std::cos(k), db = kRadius_mm * dk;
        for (int j = 0; j < kFlutes; ++j) {
            const double alpha = kPi / 2 - theta_rad - 2 * kPi * j / kFlutes + z * lag_per_mm;
            const double ca = std::cos(alpha), sa = std::sin(alpha);
            const Eigen::Vector3d n(nr * ca, nr * sa, nz);
            const double h = f_tool.dot(n);
            if (!(h > kMinChip_mm)) continue;
            // Height in workpiece axes: the centre, plus the point's offset from it turned out.
            const double z_w = kCentreZ_mm + (R * Eigen::Vector3d(r * ca, r * sa, z - kRadius_mm)).z();
            if (!(z_w < kTopZ_mm)) continue;
            const double Ft = (kKtc * h + kKte) * db, Fr = (kKrc * h + kKre) * db, Fa = (kKac * h + kKae) * db;
            const Eigen::Vector3d t(-sa, ca, 0), a(-nz * ca, -nz * sa, nr);
            sum += Ft * t - Fr * n + Fa * a;
        }
    }
    return R * sum;
}

constexpr double kFeed_mm_s = kFeedPerTooth_mm * kFlutes * kRpm / 60;
constexpr double kIdleBefore_s = 0.3;

// The cut as a path against the part: the centre along +X, the lead turning with the path's time.
app::PathDryRunSpec turning_path_spec() {
    const double duration_s = (kX1_mm - kX0_mm) / kFeed_mm_s;
    app::PathDryRunSpec s;
    s.path = [duration_s](double u) {
        const double lead = kLead0_deg + (kLead1_deg - kLead0_deg) * std::clamp(u / duration_s, 0.0, 1.0);
        const Eigen::Vector3d a = tool_axis(lead, kTilt_deg);
        const Eigen::Vector3d centre(kX0_mm + kFeed_mm_s * u, kY_mm, kCentreZ_mm);
        const Eigen::Vector3d tip = centre - kRadius_mm * a;
        app::PathPose p;
        p.tip_mm = {tip.x(), tip.y(), tip.z()};
        p.axis = {a.x(), a.y(), a.z()};
        return p;
    };
    s.duration_s = duration_s;
    s.tool_length_mm = kToolLength_mm;
    s.start_axes = {{'A', 0}, {'C', 180}};
    s.spindle_rpm = kRpm;
    s.idle_before_s = kIdleBefore_s;
    s.idle_after_s = 0.2;
    s.seed = 20261128;
    return s;
}

// The cut's dry-run log, written to `log_path` as the AC machine records it.
app::PathDryRun write_turning_log(const machine::Machine& machine, const std::string& log_path) {
    std::ostringstream csv;
    app::PathDryRun run = app::synthesize_path_dry_run(turning_path_spec(), machine, csv);
    apptest::write_text(log_path, csv.str());
    return run;
}

// The run as `cutload predict --machine` sets it up, on the OpenCL kernels where a device exists
// (their twins equal them step for step: tests/force_model/test_tri_dexel_opencl.cpp), so the
// references below check the device path.
app::RunInput turning_input(const std::string& log_path, std::shared_ptr<const machine::Machine> machine) {
    app::RunInput in;
    in.log_path = log_path;
    in.read = app::read_options(app::LogFormat{});
    in.spec = force_model::parse_run_spec_text(kSpec, "turning.json");
    in.machine = std::move(machine);
    in.tool_length_mm = kToolLength_mm;
    in.device = enginetest::opencl_available() ? force_model::Device::OpenCL : force_model::Device::Cpu;
    return in;
}

}  // namespace

TEST_CASE("turning tool: a ball end mill turning its lead from 5 to 25 deg while it cuts matches the numerical "
          "integration at each instant's orientation",
          "[five_axis][turning][physics]") {
    const auto machine = app::load_machine_definition(apptest::source_path("data/machines/ac_table_table.json"));
    apptest::Scratch dir("turning_tool");
    const std::string log_path = (dir / "turning.csv").string();
    const app::PathDryRun run = write_turning_log(*machine, log_path);
    const app::RunInput in = turning_input(log_path, machine);
    const app::RunResult r = app::predict_run(in);
    CHECK(r.turning);
    CHECK_FALSE(r.fixed_tilt);
    CHECK(r.tool_lean_deg == Approx(std::acos(tool_axis(kLead1_deg, kTilt_deg).z()) * 180 / kPi).margin(0.05));
    CHECK_THAT(r.prediction.stats.device, Catch::Contains("multi-direction stock"));

    // The machine axes at each row's time (linear between the log's repaired samples: 1 ms apart, a
    // table turning 15 deg/s moves 0.015 deg between them), then the tool frame by forward kinematics.
    const motion_io::MotionModel axes = motion_io::ingest(log_path, in.read);
    const auto frame_at = [&](double t_s) {
        const auto it = std::upper_bound(axes.t_s.begin(), axes.t_s.end(), t_s);
        const std::size_t i = std::clamp<std::size_t>(std::size_t(it - axes.t_s.begin()), 1, axes.size() - 1) - 1;
        const double w = (t_s - axes.t_s[i]) / (axes.t_s[i + 1] - axes.t_s[i]);
        const auto lerp = [&](const std::vector<double>& v) { return v[i] + w * (v[i + 1] - v[i]); };
        const machine::AxisPositions q = machine::positions(
            *machine, {{'X', lerp(axes.x_mm)}, {'Y', lerp(axes.y_mm)}, {'Z', lerp(axes.z_mm)}, {'A', lerp(axes.rot_deg[0])},
                       {'C', lerp(axes.rot_deg[2])}});
        return machine::forward(*machine, q, kToolLength_mm, machine::ErrorMode::Nominal).tool_to_workpiece.R;
    };
    // The steady window: the centre 10 to 26 mm into the stock (the ball is fully in from 5 mm; the
    // path ends at 32 mm, and its deceleration must stay out).
    const double t0 = run.path_start_s + run.lag_s + 18 / kFeed_mm_s, t1 = run.path_start_s + run.lag_s + 34 / kFeed_mm_s;
    std::vector<const force_model::ForceSample*> window;
    std::vector<Eigen::Matrix3d> frames;
    for (const auto& row : r.prediction.samples)
        if (row.t_s >= t0 && row.t_s <= t1) {
            window.push_back(&row);
            frames.push_back(frame_at(row.t_s));
        }
    REQUIRE(window.size() > 10000);
    // The rows carry the axis they cut at: the frame's, to the log's resolution.
    double worst_axis = 0;
    for (std::size_t k = 0; k < window.size(); ++k)
        worst_axis = std::max(worst_axis, (Eigen::Vector3d(window[k]->tool_axis_x, window[k]->tool_axis_y,
                                                           window[k]->tool_axis_z) - frames[k].col(2)).norm());
    CHECK(worst_axis < 1e-5);
    // The lead does turn across the window: 16 of the path's 40 mm, 8 deg.
    CHECK(std::acos(frames.front().col(2).dot(frames.back().col(2))) * 180 / kPi == Approx(8).margin(0.3));

    // The spindle angle's zero: the cutter contract's and the reference's are one, so the offset is
    // a whole tooth pitch (the fixed-tilt test fits it over a whole turn and finds that); fitted on
    // every 10th row within 6 deg of each pitch, in 0.5 deg steps.
    double best = 1e300, offset_deg = 0;
    for (double pitch : {0.0, 180.0})
        for (int o = -12; o <= 12; ++o) {
            double sq = 0;
            const double off = pitch + 0.5 * o;
            for (std::size_t k = 0; k < window.size(); k += 10) {
                const Eigen::Vector3d f = reference_forces(frames[k], (window[k]->spindle_angle_deg + off) * kPi / 180, 300);
                sq += (Eigen::Vector3d(window[k]->fx_N, window[k]->fy_N, window[k]->fz_N) - f).squaredNorm();
            }
            if (sq < best) best = sq, offset_deg = off;
        }
    const double pitch_off = std::fmod(offset_deg + 360.0, 180.0);
    CHECK(std::min(pitch_off, 180 - pitch_off) <= 2.0);   // within the angle step of a pitch
    Eigen::Vector3d mean_engine = Eigen::Vector3d::Zero(), mean_ref = Eigen::Vector3d::Zero();
    double sq = 0, peak = 0;
    for (std::size_t k = 0; k < window.size(); ++k) {
        const Eigen::Vector3d f = reference_forces(frames[k], (window[k]->spindle_angle_deg + offset_deg) * kPi / 180);
        const Eigen::Vector3d e(window[k]->fx_N, window[k]->fy_N, window[k]->fz_N);
        mean_engine += e / double(window.size());
        mean_ref += f / double(window.size());
        sq += (e - f).squaredNorm();
        peak = std::max(peak, f.norm());
    }
    const double mean_error = (mean_engine - mean_ref).norm() / mean_ref.norm();
    const double trace_rms = std::sqrt(sq / double(window.size())) / peak;
    INFO("mean (" << mean_engine.transpose() << ") N against (" << mean_ref.transpose() << ") N: " << mean_error * 100
                  << " %, trace RMS " << trace_rms * 100 << " % of the peak " << peak << " N, offset " << offset_deg
                  << " deg, " << window.size() << " rows");
    CHECK(mean_ref.norm() > 50);
    // Issue 15 asks for the traces of a tilted ball end mill within 3 %.
    CHECK(mean_error < 0.01);
    CHECK(trace_rms < 0.03);
    if (std::getenv("CUTLOAD_TILT_VERBOSE"))
        fmt::print("turning lead: mean {:.3f} %, trace RMS {:.3f} % of peak {:.1f} N, offset {} deg, {} rows\n",
                   mean_error * 100, trace_rms * 100, peak, offset_deg, window.size());
}

// The same cut with its NC program: the machine-axis program the log was made from, its pieces
// named in three blocks (N31 entering the stock, N32 and N33 in it), compared with the log. The
// commanded run is made from the program's machine axes through the chain, so its forces over the
// steady window must be the numerical integration's, as the log's are; the comparison finds the
// log on the program's tip path block by block.
TEST_CASE("turning tool: with its NC program the commanded run turns the tool as the program does, matches the "
          "integration, and the blocks compare",
          "[five_axis][turning][nc]") {
    const auto machine = app::load_machine_definition(apptest::source_path("data/machines/ac_table_table.json"));
    apptest::Scratch dir("turning_program");
    const std::string log_path = (dir / "turning.csv").string();
    const app::PathDryRun run = write_turning_log(*machine, log_path);
    // One block per third of the pieces; the log names them all N30, so it is mapped onto these.
    std::vector<std::string> lines;
    {
        std::istringstream in(run.program);
        for (std::string line; std::getline(in, line);) lines.push_back(line);
    }
    const std::string prefix = run.block + " ";
    const auto pieces = std::size_t(std::count_if(lines.begin(), lines.end(), [&](const std::string& l) { return l.rfind(prefix, 0) == 0; }));
    REQUIRE(pieces > 300);
    std::string program;
    std::size_t k = 0;
    for (std::string& line : lines) {
        if (line.rfind(prefix, 0) == 0) line = fmt::format("N{} {}", 31 + 3 * k++ / pieces, line.substr(prefix.size()));
        program += line + "\n";
    }

    app::RunInput in = turning_input(log_path, machine);
    app::ProgramSource source;
    source.text = program;
    source.name = "turning.nc";
    source.settings.work_offsets_mm["G54"] = {0, 0, 0};   // the program is in machine coordinates
    in.program = source;
    const app::RunResult r = app::predict_run(in);
    CHECK(r.turning);
    REQUIRE(r.program);
    REQUIRE(r.commanded);
    CHECK(r.program->mapped);

    // The three blocks, found on the program's tip path: the log trails the command along it.
    std::map<std::string, const force_model::BlockComparison*> blocks;
    for (const auto& b : r.commanded->blocks) blocks[b.block] = &b;
    for (const char* name : {"N31", "N32", "N33"}) {
        INFO(name);
        REQUIRE(blocks.count(name) == 1);
        const auto& b = *blocks[name];
        CHECK(b.samples > 100);
        CHECK(b.max_deviation_mm < 0.01);
    }
    // N32 runs at its programmed tip speed all through (N31 holds the start, N33 the stop); the tip
    // moves slower than the ball's centre as the lead turns: 1226 against 1280 mm/min.
    CHECK(blocks["N32"]->actual_duration_s == Approx(blocks["N32"]->commanded_duration_s).epsilon(0.01));
    CHECK(blocks["N32"]->actual_mean_feed_mm_min == Approx(blocks["N32"]->programmed_feed_mm_min).epsilon(0.005));
    CHECK(blocks["N32"]->programmed_feed_mm_min < kFeed_mm_s * 60 * 0.97);
    // N32 and N33 cut the groove whole, at the same chip: their peaks agree, commanded and actual.
    for (const char* name : {"N32", "N33"}) {
        INFO(name << ": commanded peak " << blocks[name]->commanded_peak_force_N << " N, actual "
                  << blocks[name]->actual_peak_force_N << " N");
        CHECK(blocks[name]->commanded_peak_force_N > 50);
        CHECK(std::abs(blocks[name]->force_difference_pct) < 3);
    }

    // The steady window of the first test (the centre 10 to 26 mm into the stock) in commanded time:
    // the program dwells kIdleBefore_s before the path.
    const double u0 = 18 / kFeed_mm_s, u1 = 34 / kFeed_mm_s;
    Eigen::Vector3d commanded_mean = Eigen::Vector3d::Zero();
    std::size_t n = 0;
    for (const auto& row : r.commanded->commanded.samples)
        if (row.t_s >= kIdleBefore_s + u0 && row.t_s <= kIdleBefore_s + u1) {
            commanded_mean += Eigen::Vector3d(row.fx_N, row.fy_N, row.fz_N);
            ++n;
        }
    REQUIRE(n > 10000);
    commanded_mean /= double(n);
    // The integration's mean over the window: at each instant the average over a turn of the
    // spindle, which does not depend on how the frame turns about the tool's axis.
    const double duration_s = (kX1_mm - kX0_mm) / kFeed_mm_s;
    Eigen::Vector3d reference_mean = Eigen::Vector3d::Zero();
    constexpr int kInstants = 32, kAngles = 90;
    for (int i = 0; i < kInstants; ++i) {
        const double u = u0 + (u1 - u0) * (i + 0.5) / kInstants;
        const Eigen::Vector3d a = tool_axis(kLead0_deg + (kLead1_deg - kLead0_deg) * u / duration_s, kTilt_deg);
        const Eigen::Matrix3d R = Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), a).toRotationMatrix();
        for (int j = 0; j < kAngles; ++j) reference_mean += reference_forces(R, 2 * kPi * (j + 0.5) / kAngles, 300);
    }
    reference_mean /= double(kInstants * kAngles);
    // The log's rows over the same stretch of path (it trails the command by the lag).
    Eigen::Vector3d actual_mean = Eigen::Vector3d::Zero();
    std::size_t m = 0;
    for (const auto& row : r.prediction.samples)
        if (row.t_s >= run.path_start_s + run.lag_s + u0 && row.t_s <= run.path_start_s + run.lag_s + u1) {
            actual_mean += Eigen::Vector3d(row.fx_N, row.fy_N, row.fz_N);
            ++m;
        }
    REQUIRE(m > 10000);
    actual_mean /= double(m);
    INFO("commanded mean (" << commanded_mean.transpose() << ") N, actual (" << actual_mean.transpose()
                            << ") N, integration (" << reference_mean.transpose() << ") N");
    CHECK(reference_mean.norm() > 50);
    CHECK((commanded_mean - reference_mean).norm() / reference_mean.norm() < 0.01);
    CHECK((commanded_mean - actual_mean).norm() / reference_mean.norm() < 0.01);
    if (std::getenv("CUTLOAD_TILT_VERBOSE"))
        fmt::print("turning program: commanded {:.3f} % and actual {:.3f} % off the integration's mean\n",
                   100 * (commanded_mean - reference_mean).norm() / reference_mean.norm(),
                   100 * (actual_mean - reference_mean).norm() / reference_mean.norm());
}
