// Straight cuts at constant feed in a box: predict() against Altintas' closed-form averages
// (within 2 %) and against the independent numerical integration of the same model (within 3 %).
//
// Metrics: mean error = |mean F_engine - mean F_closed| / |mean F_closed| (force vectors), over
// whole tooth periods of the steady part; torque relative to the closed-form torque. Trace error
// = RMS over the steady part of |F_engine - F_reference| / peak reference resultant, with the
// engine's spindle-angle zero fitted once per run (the contract does not fix it).
#include "force_model/reference.hpp"

#include <catch2/catch.hpp>
#include <fmt/format.h>

#include <cmath>
#include <numbers>
#include <vector>

using namespace cutload;
using namespace cutload::testref;

namespace {

constexpr double kRpm = 10000;
constexpr double kGridMm = 0.02;

std::string describe(const Cut& c) {
    return fmt::format("D{} N{} helix{} a{} c{} phi[{:.1f},{:.1f}]deg", c.diameter_mm, c.flutes, c.helix_deg,
                       c.axial_depth_mm, c.feed_per_tooth_mm, c.phi_start_rad * 180 / std::numbers::pi,
                       c.phi_exit_rad * 180 / std::numbers::pi);
}

// Checks one cut on every device; returns the fitted spindle-angle offset per device.
std::vector<double> check_straight_cut(const Cut& cut) {
    const Coefficients k = test_coefficients();
    const StraightSetup setup = straight_setup(cut, kRpm);
    const motion_io::MotionModel motion = uniform_motion(setup.path);
    const force_model::RunSpec spec = flat_tool_spec(cut, k, setup.box, kGridMm);
    const Forces expected = average_forces(cut, k);
    const double omega_rad_s = 2 * std::numbers::pi * kRpm / 60.0;

    std::vector<Forces> means;
    std::vector<double> offsets_deg;
    for (force_model::Device device : devices_under_test()) {
        force_model::PredictOptions opt;
        opt.device = device;
        const force_model::Prediction p = force_model::predict(motion, spec, opt);
        const SteadyMean m = steady_mean(p.samples, setup.steady_t0_s, setup.steady_t1_s, cut.flutes);
        const TraceFit fit = fit_trace(p.samples, setup.steady_t0_s, setup.steady_t1_s, cut, k);
        const double mean_err = relative_force_error(m.forces, expected);
        const double torque_err = std::abs(m.forces.torque_Nm / expected.torque_Nm - 1);
        const std::string figures = fmt::format(
            "{} {}: mean F ({:.3f},{:.3f},{:.3f}) N vs closed ({:.3f},{:.3f},{:.3f}) err {:.3f}%; torque {:.4f} vs "
            "{:.4f} N m err {:.3f}%; trace rms {:.3f}% torque rms {:.3f}% (offset {:.2f} deg, {} rows, {} periods, "
            "max gap {:.2f} deg); {:.2f} s wall",
            device_name(device), describe(cut), m.forces.fx_N, m.forces.fy_N, m.forces.fz_N, expected.fx_N,
            expected.fy_N, expected.fz_N, 100 * mean_err, m.forces.torque_Nm, expected.torque_Nm, 100 * torque_err,
            100 * fit.rms_rel, 100 * fit.torque_rms_rel, fit.offset_deg, fit.samples, m.tooth_periods,
            m.max_angle_gap_deg, p.stats.wall_s);
        report_figure(figures);
        INFO(figures);
        REQUIRE(m.tooth_periods >= 10);
        CHECK(m.max_angle_gap_deg <= spec.resolution.angle_step_deg * 1.05);
        CHECK(mean_err < 0.02);
        CHECK(torque_err < 0.02);
        CHECK(m.power_kW == Approx(m.forces.torque_Nm * omega_rad_s / 1000.0).epsilon(0.01));
        CHECK(fit.rms_rel < 0.03);
        CHECK(fit.torque_rms_rel < 0.03);
        means.push_back(m.forces);
        offsets_deg.push_back(fit.offset_deg);
    }
    if (means.size() == 2) {
        INFO(describe(cut) << ": OpenCL vs CPU mean forces");
        CHECK(relative_force_error(means[1], means[0]) < 0.005);
    }
    return offsets_deg;
}

}  // namespace

TEST_CASE("physics: slot at constant feed matches the closed form and the numerical trace", "[physics][straight]") {
    check_straight_cut(slot_cut(8, 2, 30, 2, 0.1));
}

TEST_CASE("physics: up milling at several radial depths", "[physics][straight]") {
    for (double ae_mm : {1.0, 3.0, 6.0}) check_straight_cut(up_cut(8, 2, 30, 2, 0.1, ae_mm));
}

TEST_CASE("physics: down milling at several radial depths", "[physics][straight]") {
    for (double ae_mm : {1.0, 3.0, 6.0}) check_straight_cut(down_cut(8, 2, 30, 2, 0.1, ae_mm));
}

TEST_CASE("physics: a second tool (D 6, 4 flutes, 45 deg helix) in slot, up and down milling",
          "[physics][straight]") {
    check_straight_cut(slot_cut(6, 4, 45, 1.5, 0.05));
    check_straight_cut(up_cut(6, 4, 45, 1.5, 0.05, 1.5));
    check_straight_cut(down_cut(6, 4, 45, 1.5, 0.05, 2.0));
}

TEST_CASE("physics: the helix lags upwards (trace phase does not depend on the axial depth)", "[physics][straight]") {
    // A helix lagging the wrong way gives the same trace shifted by 2 a tan(beta) / D, which the
    // fitted angle offset would absorb; so the offset itself must not move with the axial depth.
    // Here a reversed lag would shift it by 2 * 2 mm * tan 30 / 8 mm = 16.5 deg between a = 1 and 3.
    const std::vector<double> shallow = check_straight_cut(up_cut(8, 2, 30, 1, 0.1, 3));
    const std::vector<double> deep = check_straight_cut(up_cut(8, 2, 30, 3, 0.1, 3));
    REQUIRE(shallow.size() == deep.size());
    for (std::size_t i = 0; i < shallow.size(); ++i) {
        const double shift_deg = std::remainder(deep[i] - shallow[i], 180.0);
        report_figure(fmt::format("trace phase shift between a = 1 and 3 mm: {:.3f} deg", shift_deg));
        CHECK(std::abs(shift_deg) < 1.0);
    }
}
