// Engagement and forces for a tool at any orientation on the tri-dexel stock
// (kernels::engage_tri_dexel, docs/five_axis.md section 4), against the closed-form mean forces of
// Altintas' model (reference.hpp): a vertical side cut, the same cut turned so the tool lies
// horizontal, and a tool that only turns (the chip from the rotation, omega x r).
#include "force_model/cutters/shapes.hpp"
#include "force_model/cutters/tool_geometry.hpp"
#include "force_model/engine/pose_engine.hpp"
#include "force_model/reference.hpp"
#include "kernels/tri_dexel.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>

using namespace cutload;
using Vec = std::array<double, 3>;
using Mat = std::array<Vec, 3>;   // rows

namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kCellMm = 0.1;

struct Setup {
    force_model::ToolGeometry geometry;
    kernels::EngageParams params;
};

Setup flat_end_mill(const testref::Cut& cut) {
    const force_model::Cutter cutter{force_model::corner_radius_profile(cut.diameter_mm, 0, 20), cut.flutes,
                                     cut.helix_deg, 30, 0, 0};
    Setup s{force_model::build_tool_geometry(cutter, 0.05), {}};
    const testref::Coefficients k = testref::test_coefficients();
    s.params.k = {k.Ktc_N_mm2, k.Krc_N_mm2, k.Kac_N_mm2, k.Kte_N_mm, k.Kre_N_mm, k.Kae_N_mm};
    s.params.element_end = int(s.geometry.edges.size());
    return s;
}

Vec apply(const Mat& m, const Vec& v) {
    return {m[0][0] * v[0] + m[0][1] * v[1] + m[0][2] * v[2], m[1][0] * v[0] + m[1][1] * v[1] + m[1][2] * v[2],
            m[2][0] * v[0] + m[2][1] * v[1] + m[2][2] * v[2]};
}

constexpr Mat kIdentity{{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}};

// Mean forces (stock frame) over one tooth period of a tool held at `tip` with orientation `rot`,
// feeding `feed_tool` per tooth and turning `turn_tool` per tooth (tool frame), on the stock.
Vec mean_force(const Setup& s, const kernels::TriDexel& stock, const Vec& tip, const Mat& rot, const Vec& feed_tool,
               const Vec& turn_tool, int flutes, double* torque_Nmm = nullptr) {
    const int steps = 720;
    std::vector<kernels::PoseStep> poses(steps);
    for (int i = 0; i < steps; ++i) {
        kernels::PoseStep& p = poses[i];
        p.tip_mm = tip;
        p.rot = rot;
        p.feed_mm = feed_tool;
        p.turn_rad = turn_tool;
        p.theta_rad = 2 * kPi / flutes * (i + 0.5) / steps;
    }
    std::vector<kernels::StepResult> out(steps);
    kernels::engage_tri_dexel(poses.data(), poses.size(), 1.0, s.geometry.edges, s.params, stock, out.data());
    Vec sum{0, 0, 0};
    double t = 0;
    for (const auto& o : out) {
        sum[0] += o.fx_N;
        sum[1] += o.fy_N;
        sum[2] += o.fz_N;
        t += o.torque_Nmm;
    }
    if (torque_Nmm) *torque_Nmm = t / steps;
    return {sum[0] / steps, sum[1] / steps, sum[2] / steps};
}

// The material box that gives the cut's immersion window to a tool whose tip is at the origin
// feeding along +X (reference.hpp's convention: cutting points at R (sin phi, cos phi), up milling
// from phi = 0 on the +Y side), between heights z0 and z0 + a_p.
std::pair<Vec, Vec> window_box(const testref::Cut& cut, double z0_mm) {
    const double R = cut.diameter_mm / 2;
    const double y_lo = cut.phi_start_rad > 0 ? -R - 5 : R * std::cos(cut.phi_exit_rad);
    const double y_hi = cut.phi_start_rad > 0 ? R * std::cos(cut.phi_start_rad) : R + 5;
    return {{-12.03, y_lo, z0_mm}, {12.07, y_hi, z0_mm + cut.axial_depth_mm}};
}

void check_close(const Vec& got, const testref::Forces& want, double tol) {
    const double scale = std::hypot(want.fx_N, want.fy_N, want.fz_N);
    INFO("got (" << got[0] << ", " << got[1] << ", " << got[2] << ") N, want (" << want.fx_N << ", " << want.fy_N
                 << ", " << want.fz_N << ") N");
    CHECK(std::abs(got[0] - want.fx_N) <= tol * scale);
    CHECK(std::abs(got[1] - want.fy_N) <= tol * scale);
    CHECK(std::abs(got[2] - want.fz_N) <= tol * scale);
}

}  // namespace

TEST_CASE("tri-dexel engagement: a vertical side cut gives Altintas' closed-form mean forces", "[tri_dexel]") {
    const double fz_mm = 0.1;
    for (const testref::Cut& cut : {testref::up_cut(8, 2, 30, 2, fz_mm, 2), testref::down_cut(8, 2, 30, 2, fz_mm, 3),
                                    testref::slot_cut(8, 2, 30, 2, fz_mm)}) {
        const Setup s = flat_end_mill(cut);
        // The tip 0.5 mm below the material: the flat bottom stays in air, as in the closed form.
        const auto [lo, hi] = window_box(cut, 0.5);
        const auto stock = kernels::make_tri_dexel_box(lo, hi, kCellMm);
        double torque = 0;
        const Vec f = mean_force(s, stock, {0, 0, 0}, kIdentity, {fz_mm, 0, 0}, {0, 0, 0}, cut.flutes, &torque);
        const testref::Forces want = testref::average_forces(cut, testref::test_coefficients());
        INFO("window " << cut.phi_start_rad << " to " << cut.phi_exit_rad << " rad");
        check_close(f, want, 0.005);
        CHECK(torque / 1000 == Approx(want.torque_Nm).epsilon(0.005));
    }
}

TEST_CASE("tri-dexel engagement: the side cut turned so the tool lies horizontal gives the same forces, turned",
          "[tri_dexel]") {
    // Q turns the vertical set-up about Y by -90 deg: the tool axis +Z becomes -X, +X becomes +Z.
    // The stock box turns with it (still a box), and the forces must be Q times the vertical ones.
    const testref::Cut cut = testref::up_cut(8, 2, 30, 2, 0.1, 2);
    const Setup s = flat_end_mill(cut);
    const Mat Q{{{0, 0, -1}, {0, 1, 0}, {1, 0, 0}}};
    const auto [lo, hi] = window_box(cut, 0.5);
    const Vec a = apply(Q, lo), b = apply(Q, hi);
    const Vec turned_lo{std::min(a[0], b[0]), std::min(a[1], b[1]), std::min(a[2], b[2])};
    const Vec turned_hi{std::max(a[0], b[0]), std::max(a[1], b[1]), std::max(a[2], b[2])};
    const auto vertical = kernels::make_tri_dexel_box(lo, hi, kCellMm);
    const auto horizontal = kernels::make_tri_dexel_box(turned_lo, turned_hi, kCellMm);
    const Vec tip{0, 0, 0};
    const Vec f_vertical = mean_force(s, vertical, tip, kIdentity, {0.1, 0, 0}, {0, 0, 0}, 2);
    const Vec f_horizontal = mean_force(s, horizontal, tip, Q, {0.1, 0, 0}, {0, 0, 0}, 2);
    const Vec want = apply(Q, f_vertical);
    const double scale = std::hypot(want[0], want[1], want[2]);
    for (int c = 0; c < 3; ++c) CHECK(std::abs(f_horizontal[c] - want[c]) <= 1e-6 * scale);
    check_close(f_horizontal,
                [&] {
                    const testref::Forces r = testref::average_forces(cut, testref::test_coefficients());
                    const Vec t = apply(Q, {r.fx_N, r.fy_N, r.fz_N});
                    return testref::Forces{t[0], t[1], t[2], r.torque_Nm};
                }(),
                0.005);
}

TEST_CASE("tri-dexel engagement: a tool that only turns cuts with the chip of omega x r", "[tri_dexel]") {
    // The tip stands still while the tool turns about its own y axis through the tip by w per tooth:
    // a point at height z feeds w z along +x. Over the material from z = 0.5 to 2.5 the chip grows
    // linearly with z, and the mean force is linear in the chip, so it equals the closed form at the
    // mean feed w (0.5 + 2.5) / 2 with a_p = 2.
    const double w_rad = 0.1 / 1.5;
    const testref::Cut cut = testref::up_cut(8, 2, 30, 2, 0.1, 2);
    const Setup s = flat_end_mill(cut);
    const auto [lo, hi] = window_box(cut, 0.5);
    const auto stock = kernels::make_tri_dexel_box(lo, hi, kCellMm);
    const Vec f = mean_force(s, stock, {0, 0, 0}, kIdentity, {0, 0, 0}, {0, w_rad, 0}, 2);
    check_close(f, testref::average_forces(cut, testref::test_coefficients()), 0.005);
    // Turning the other way the front half feeds backwards: with material only ahead of the
    // tool (x > 0), no chip and no force.
    const auto ahead = kernels::make_tri_dexel_box({0.0, lo[1], lo[2]}, hi, kCellMm);
    const Vec back = mean_force(s, ahead, {0, 0, 0}, kIdentity, {0, 0, 0}, {0, -w_rad, 0}, 2);
    CHECK(std::hypot(back[0], back[1], back[2]) < 1e-9);
}

TEST_CASE("tri-dexel engagement: a side cut against a wall left between grid lines by an earlier pass", "[tri_dexel]") {
    // An earlier pass of a D20 flat end mill along X leaves the wall y = 2.037, off the grid's
    // lines, so the Z and X rays place it only to a cell while the Y rays place it exactly. The
    // up-milling cut (ae 2, D8) then runs with its centre at y = 0.037: its window ends on that wall.
    const testref::Cut cut = testref::up_cut(8, 2, 30, 2, 0.1, 2);
    const Setup s = flat_end_mill(cut);
    const double y_shift = 0.037, wall_y = y_shift + 4 * std::cos(cut.phi_exit_rad);
    auto stock = kernels::make_tri_dexel_box({-12.03, -9.99, 0.5}, {12.07, 10.01, 2.5}, kCellMm);
    std::vector<std::array<double, 2>> flat20{{0, 0}, {10, 0}, {10, 20}};
    const auto big = kernels::convex_tool_solid(flat20);
    kernels::ToolChord pass;
    pass.from_mm = {-30, wall_y - 10, 0};
    pass.to_mm = {30, wall_y - 10, 0};
    pass.rot = kIdentity;
    const auto removed = kernels::sweep_tri_dexel(stock, big, &pass, 1);
    CHECK(removed[1] == Approx((wall_y + 9.99) * 24.1 * 2).epsilon(1e-4));   // the Y rays: exact
    const Vec f = mean_force(s, stock, {0, y_shift, 0}, kIdentity, {0.1, 0, 0}, {0, 0, 0}, 2);
    check_close(f, testref::average_forces(cut, testref::test_coefficients()), 0.005);
}

TEST_CASE("tri-dexel pose engine: a side cut through the stock, removing as it goes, gives the closed-form mean forces",
          "[tri_dexel]") {
    // Up milling, D8, ae 2, ap 2, 0.1 mm per tooth at 6000 rpm (20 mm/s), 2 deg per step. The tool
    // enters the block y 2..9, x 0..30 from outside and runs to x = 20; the engine engages each
    // batch against the stock its earlier sweep left (trailing by the lag) and removes as it goes.
    const testref::Cut cut = testref::up_cut(8, 2, 30, 2, 0.1, 2);
    const Setup s = flat_end_mill(cut);
    const double rpm = 6000, v_mm_s = 0.1 * 2 * rpm / 60, dt_s = (2.0 / 360) / (rpm / 60);
    const double x0 = -6, x1 = 20;
    const auto n = std::size_t(std::llround((x1 - x0) / v_mm_s / dt_s));
    const force_model::Device device = GENERATE(from_range(testref::devices_under_test()));
    force_model::PoseEngineSettings settings;
    settings.opencl = device == force_model::Device::OpenCL;
    for (const bool horizontal : {false, true}) {
        INFO((horizontal ? "tool horizontal (the set-up turned by Q)" : "tool vertical") << ", " << testref::device_name(device));
        // Q turns about Y by -90 deg: the tool axis +Z becomes -X.
        const Mat rot = horizontal ? Mat{{{0, 0, -1}, {0, 1, 0}, {1, 0, 0}}} : kIdentity;
        const Vec a = apply(rot, {0, 2, 0.5}), b = apply(rot, {30, 9, 2.5});
        auto stock = kernels::make_tri_dexel_box({std::min(a[0], b[0]), std::min(a[1], b[1]), std::min(a[2], b[2])},
                                                 {std::max(a[0], b[0]), std::max(a[1], b[1]), std::max(a[2], b[2])},
                                                 kCellMm);
        std::vector<kernels::PoseStep> steps(n);
        for (std::size_t i = 0; i < n; ++i) {
            const double t = i * dt_s;
            steps[i].tip_mm = apply(rot, {x0 + v_mm_s * t, 0, 0});
            steps[i].rot = rot;
            steps[i].feed_mm = {0.1, 0, 0};
            steps[i].theta_rad = 2 * kPi * rpm / 60 * t;
        }
        std::vector<std::array<double, 2>> rz;
        for (const auto& p : force_model::profile_polyline(force_model::corner_radius_profile(8, 0, 20), kCellMm / 64))
            rz.push_back({p.r_mm, p.z_mm});
        force_model::PoseEngine engine(std::move(stock), s.geometry, kernels::convex_tool_solid(rz), s.params, settings);
        std::vector<kernels::StepResult> out;
        engine.run(steps, out, 1.0);
        engine.finish();
        // Mean over whole tooth periods (90 steps) while the centre runs from x = 8 to 18.
        const auto i0 = std::size_t(std::llround((8 - x0) / v_mm_s / dt_s));
        const std::size_t periods = std::size_t(std::llround(10 / v_mm_s / dt_s)) / 90;
        Vec sum{0, 0, 0};
        for (std::size_t i = i0; i < i0 + periods * 90; ++i) {
            sum[0] += out[i].fx_N;
            sum[1] += out[i].fy_N;
            sum[2] += out[i].fz_N;
        }
        const Vec mean{sum[0] / (periods * 90.0), sum[1] / (periods * 90.0), sum[2] / (periods * 90.0)};
        const testref::Forces r = testref::average_forces(cut, testref::test_coefficients());
        const Vec want = apply(rot, {r.fx_N, r.fy_N, r.fz_N});
        check_close(mean, {want[0], want[1], want[2], r.torque_Nm}, 0.005);
        // The band the tool swept: y 2..4 over x 0..20 and the arc of its last position, ap 2.
        const double end_arc = 8 * kPi / 2 - (std::sqrt(12.0) + 8 * kPi / 6);
        CHECK(engine.removed_mm3() == Approx((40 + end_arc) * 2).epsilon(0.005));
        // The tool stops in the block, so its last tooth period still cuts (the cut is interrupted:
        // 60 deg of immersion and 16.5 deg of helix lag in 180 deg of pitch); its first steps, 2 mm
        // clear of the block, do not.
        CHECK(std::any_of(out.end() - 90, out.end(), [](const auto& o) { return o.engaged > 0; }));
        CHECK(std::none_of(out.begin(), out.begin() + 90, [](const auto& o) { return o.engaged > 0; }));
    }
}

namespace {

// The same edge elements, cutting where they lie below the flat top face z = top_mm and feed into
// it (h > min chip), with the fraction of each element's span below the face: for a convex tool fed
// straight, the leading side below the face is exactly the surface against uncut material, so this
// is the engagement without any stock. Forces by the same law (reference.hpp's Altintas model:
// Ft, Fr, Fa on the edge, summed in the tool frame, turned into the stock frame).
Vec face_cut_force(const Setup& s, const kernels::PoseStep& st, double top_mm, double spin) {
    const kernels::EdgeTable& t = s.geometry.edges;
    const auto& k = s.params.k;
    const double pitch = 2 * kPi / t.flutes;
    Vec F{0, 0, 0};
    auto world_z = [&](double x, double y, double z) {
        return st.tip_mm[2] + st.rot[2][0] * x + st.rot[2][1] * y + st.rot[2][2] * z;
    };
    for (int j = 0; j < t.flutes; ++j)
        for (std::size_t e = 0; e < t.size(); ++e) {
            const double alpha = kPi / 2 - st.theta_rad - j * pitch + spin * t.lag_rad[e];
            const double cu = std::cos(alpha), su = std::sin(alpha);
            const double h = t.nr[e] * (st.feed_mm[0] * cu + st.feed_mm[1] * su) + t.nz[e] * st.feed_mm[2];
            if (h <= s.params.min_chip_mm) continue;
            const double r = t.r_mm[e];
            const double za = world_z(r * cu, r * su, t.z_lo_mm[e]), zb = world_z(r * cu, r * su, t.z_hi_mm[e]);
            double w = 0;
            if (t.z_hi_mm[e] > t.z_lo_mm[e]) {
                const double lo = std::min(za, zb), hi = std::max(za, zb);
                w = hi > lo ? std::clamp((top_mm - lo) / (hi - lo), 0.0, 1.0) : (lo < top_mm ? 1.0 : 0.0);
            } else {
                w = world_z(r * cu, r * su, t.z_mm[e]) < top_mm ? 1.0 : 0.0;
            }
            if (w <= 0) continue;
            const double db = t.db_mm[e] * w;
            const double dFt = (k.Ktc * h + k.Kte) * db, dFr = (k.Krc * h + k.Kre) * db, dFa = (k.Kac * h + k.Kae) * db;
            const double normal = dFr * t.nr[e] + dFa * t.nz[e];
            const Vec f_tool{-spin * dFt * su - normal * cu, spin * dFt * cu - normal * su, -dFr * t.nz[e] + dFa * t.nr[e]};
            const Vec f = apply(st.rot, f_tool);
            for (int c = 0; c < 3; ++c) F[c] += f[c];
        }
    return F;
}

}  // namespace

TEST_CASE("tri-dexel pose engine: a tilted ball end mill's cut matches the same edge cutting below the face",
          "[tri_dexel]") {
    // Ball D10, 2 flutes, 30 deg helix, 8000 rpm, 0.08 mm per tooth along +X, tip 2 mm below the
    // top face z = 0 of the block x 0..40, y -15..15, z -20..0; the axis leans by a lead (toward
    // +X) and a tilt (toward +Y). The reference (face_cut_force) needs no stock.
    const double R = 5, rpm = 8000, fz_mm = 0.08;
    const double v_mm_s = fz_mm * 2 * rpm / 60, dt_s = (2.0 / 360) / (rpm / 60);
    const force_model::Cutter cutter{force_model::corner_radius_profile(2 * R, R, 20), 2, 30, 30, 0, 0};
    Setup s{force_model::build_tool_geometry(cutter, 0.1), {}};
    const testref::Coefficients kc = testref::test_coefficients();
    s.params.k = {kc.Ktc_N_mm2, kc.Krc_N_mm2, kc.Kac_N_mm2, kc.Kte_N_mm, kc.Kre_N_mm, kc.Kae_N_mm};
    s.params.min_chip_mm = 5e-4;
    s.params.element_end = int(s.geometry.edges.size());
    std::vector<std::array<double, 2>> rz;
    for (const auto& p : force_model::profile_polyline(cutter.profile, kCellMm / 64)) rz.push_back({p.r_mm, p.z_mm});
    const auto [lead_deg, tilt_deg] = GENERATE(std::pair{0.0, 0.0}, std::pair{30.0, 0.0}, std::pair{15.0, 20.0},
                                               std::pair{-20.0, -10.0});
    const force_model::Device device = GENERATE(from_range(testref::devices_under_test()));
    INFO("lead " << lead_deg << " deg, tilt " << tilt_deg << " deg, " << testref::device_name(device));
    force_model::PoseEngineSettings settings;
    settings.opencl = device == force_model::Device::OpenCL;
    const double lead = lead_deg * kPi / 180, tilt = tilt_deg * kPi / 180;
    const Vec axis{std::sin(lead) * std::cos(tilt), std::sin(tilt), std::cos(lead) * std::cos(tilt)};
    // Tool x: +X made normal to the axis; y = axis x x.
    Vec x{1 - axis[0] * axis[0], -axis[0] * axis[1], -axis[0] * axis[2]};
    const double nx = std::hypot(x[0], x[1], x[2]);
    for (double& c : x) c /= nx;
    const Vec y{axis[1] * x[2] - axis[2] * x[1], axis[2] * x[0] - axis[0] * x[2], axis[0] * x[1] - axis[1] * x[0]};
    const Mat rot{{{x[0], y[0], axis[0]}, {x[1], y[1], axis[1]}, {x[2], y[2], axis[2]}}};
    // The feed per tooth along +X in the tool frame: rot^T (fz, 0, 0).
    const Vec feed_tool{rot[0][0] * fz_mm, rot[0][1] * fz_mm, rot[0][2] * fz_mm};
    const double x0 = -8, x1 = 17;
    const auto n = std::size_t(std::llround((x1 - x0) / v_mm_s / dt_s));
    std::vector<kernels::PoseStep> steps(n);
    for (std::size_t i = 0; i < n; ++i) {
        const double t = i * dt_s;
        steps[i].tip_mm = {x0 + v_mm_s * t, 0, -2};
        steps[i].rot = rot;
        steps[i].feed_mm = feed_tool;
        steps[i].theta_rad = 2 * kPi * rpm / 60 * t;
    }
    force_model::PoseEngine engine(kernels::make_tri_dexel_box({0, -15, -20}, {40, 15, 0}, kCellMm), s.geometry,
                                   kernels::convex_tool_solid(rz), s.params, settings);
    std::vector<kernels::StepResult> out;
    engine.run(steps, out, 1.0);
    // Steady stretch: the tip from x = 8 to 16, whole tooth periods (90 steps each).
    const auto i0 = std::size_t(std::llround((8 - x0) / v_mm_s / dt_s));
    const std::size_t m = std::size_t(std::llround(8 / v_mm_s / dt_s)) / 90 * 90;
    Vec mean_engine{0, 0, 0}, mean_ref{0, 0, 0};
    double diff2 = 0, peak = 0;
    for (std::size_t i = i0; i < i0 + m; ++i) {
        const Vec ref = face_cut_force(s, steps[i], 0.0, 1.0);
        const Vec got{out[i].fx_N, out[i].fy_N, out[i].fz_N};
        for (int c = 0; c < 3; ++c) {
            mean_engine[c] += got[c] / double(m);
            mean_ref[c] += ref[c] / double(m);
            diff2 += (got[c] - ref[c]) * (got[c] - ref[c]) / double(m);
        }
        peak = std::max(peak, std::hypot(ref[0], ref[1], ref[2]));
    }
    const double mean_err = std::hypot(mean_engine[0] - mean_ref[0], mean_engine[1] - mean_ref[1], mean_engine[2] - mean_ref[2]) /
                            std::hypot(mean_ref[0], mean_ref[1], mean_ref[2]);
    const double trace_rms = std::sqrt(diff2) / peak;
    INFO("mean (" << mean_engine[0] << ", " << mean_engine[1] << ", " << mean_engine[2] << ") N against ("
                  << mean_ref[0] << ", " << mean_ref[1] << ", " << mean_ref[2] << ") N: " << mean_err * 100
                  << " %, trace RMS " << trace_rms * 100 << " % of the peak " << peak << " N");
    CHECK(peak > 50);
    // Issue 15 asks for 3 % on the traces of a tilted ball end mill.
    CHECK(mean_err < 0.01);
    CHECK(trace_rms < 0.03);
    testref::report_figure(std::string("tri-dexel tilted ball (") + testref::device_name(device) + ") lead " +
                           std::to_string(lead_deg) + " tilt " + std::to_string(tilt_deg) +
                           ": mean " + std::to_string(mean_err * 100) + " %, trace RMS " + std::to_string(trace_rms * 100) +
                           " % of peak");
}
