// The reference itself, checked against numbers worked out by hand before it is trusted to judge
// the engine.
#include "force_model/reference.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <numbers>

using namespace cutload::testref;

namespace {

constexpr double pi = std::numbers::pi;

// Mean of instantaneous_forces() over one tooth period by the midpoint rule.
Forces numerical_period_mean(const Cut& cut, const Coefficients& k, int steps) {
    Forces sum;
    const double period = 2 * pi / cut.flutes;
    for (int i = 0; i < steps; ++i) {
        const Forces f = instantaneous_forces(cut, k, (i + 0.5) * period / steps, 200);
        sum.fx_N += f.fx_N / steps;
        sum.fy_N += f.fy_N / steps;
        sum.fz_N += f.fz_N / steps;
        sum.torque_Nm += f.torque_Nm / steps;
    }
    return sum;
}

}  // namespace

TEST_CASE("physics reference: slot closed form matches the hand-derived averages", "[physics][reference]") {
    // N = 2, a = 2 mm, c = 0.1 mm, R = 4 mm, K = test_coefficients():
    //   Fx = -N a c Krc / 4 - N a Kre / pi = -21 - 112 / pi            = -56.650707
    //   Fy =  N a c Ktc / 4 + N a Kte / pi =  70 + 80 / pi             =  95.464791
    //   Fz =  N a c Kac / pi + N a Kae / 2 =  48 / pi + 4              =  19.278875
    //   T  =  N a R (c Ktc / pi + Kte / 2) = 16 (70 / pi + 10) N mm    =   0.5165071 N m
    const Forces f = average_forces(slot_cut(8, 2, 30, 2, 0.1), test_coefficients());
    CHECK(f.fx_N == Approx(-56.650707).epsilon(1e-6));
    CHECK(f.fy_N == Approx(95.464791).epsilon(1e-6));
    CHECK(f.fz_N == Approx(19.278875).epsilon(1e-6));
    CHECK(f.torque_Nm == Approx(0.5165071).epsilon(1e-6));
}

TEST_CASE("physics reference: up and down milling windows and averages", "[physics][reference]") {
    CHECK(up_milling_exit_rad(2, 8) == Approx(pi / 3));
    CHECK(down_milling_start_rad(2, 8) == Approx(2 * pi / 3));
    CHECK(up_milling_exit_rad(8, 8) == Approx(pi));
    CHECK(down_milling_start_rad(8, 8) == Approx(0).margin(1e-12));

    // Up milling, ae = 2 mm of D 8 (phi 0..60 deg), by hand:
    //   Fx = (0.4 / 8pi)[700 (cos120 - 1) - 210 (2pi/3 - sin120)] + (4 / 2pi)[-20 sin60 + 28 (cos60 - 1)]
    //      = 0.0159155 (-1050 - 257.96) + 0.63662 (-31.3205) = -40.75605
    // and the rest by an independent midpoint-rule integration of the element forces.
    const Forces up = average_forces(up_cut(8, 2, 30, 2, 0.1, 2), test_coefficients());
    CHECK(up.fx_N == Approx(-40.756047).epsilon(1e-6));
    CHECK(up.fy_N == Approx(-0.399314).epsilon(1e-5));
    CHECK(up.fz_N == Approx(5.153052).epsilon(1e-6));
    CHECK(up.torque_Nm == Approx(0.1424601).epsilon(1e-6));

    const Forces down = average_forces(down_cut(8, 2, 30, 2, 0.1, 2), test_coefficients());
    CHECK(down.fx_N == Approx(14.719647).epsilon(1e-6));
    CHECK(down.fy_N == Approx(40.501865).epsilon(1e-6));
    CHECK(down.fz_N == Approx(5.153052).epsilon(1e-6));
    CHECK(down.torque_Nm == Approx(0.1424601).epsilon(1e-6));

    // Up milling at ae plus down milling at D - ae cover the slot's window exactly once.
    const Forces up3 = average_forces(up_cut(8, 2, 30, 2, 0.1, 3), test_coefficients());
    const Forces down5 = average_forces(down_cut(8, 2, 30, 2, 0.1, 5), test_coefficients());
    const Forces slot = average_forces(slot_cut(8, 2, 30, 2, 0.1), test_coefficients());
    CHECK(up3.fx_N + down5.fx_N == Approx(slot.fx_N));
    CHECK(up3.fy_N + down5.fy_N == Approx(slot.fy_N));
    CHECK(up3.fz_N + down5.fz_N == Approx(slot.fz_N));
    CHECK(up3.torque_Nm + down5.torque_Nm == Approx(slot.torque_Nm));
}

TEST_CASE("physics reference: one straight flute at 90 degrees gives the element forces", "[physics][reference]") {
    // N = 1, no helix, a = 1 mm, c = 0.1 mm at phi = 90 deg: h = 0.1 mm,
    // Ft = 70 + 20 = 90 N, Fr = 21 + 28 = 49 N, Fa = 12 + 2 = 14 N -> F = (-Fr, Ft, Fa), T = 4 mm * 90 N.
    const Forces f = instantaneous_forces(slot_cut(8, 1, 0, 1, 0.1), test_coefficients(), pi / 2, 50);
    CHECK(f.fx_N == Approx(-49.0));
    CHECK(f.fy_N == Approx(90.0));
    CHECK(f.fz_N == Approx(14.0));
    CHECK(f.torque_Nm == Approx(0.36));
    // Outside the window nothing cuts.
    const Forces none = instantaneous_forces(up_cut(8, 1, 0, 1, 0.1, 1), test_coefficients(), pi / 2, 50);
    CHECK(resultant_N(none) == 0.0);
}

TEST_CASE("physics reference: numerical integration averages to the closed form for any helix",
          "[physics][reference]") {
    const Coefficients k = test_coefficients();
    for (const Cut& cut : {slot_cut(8, 2, 30, 2, 0.1), up_cut(8, 3, 45, 3, 0.08, 1.5),
                           down_cut(12, 4, 0, 2.5, 0.12, 4), down_cut(6, 2, 40, 1.4, 0.05, 0.6)}) {
        const Forces closed = average_forces(cut, k);
        const Forces numeric = numerical_period_mean(cut, k, 3600);
        INFO("D " << cut.diameter_mm << " N " << cut.flutes << " helix " << cut.helix_deg);
        CHECK(relative_force_error(numeric, closed) < 2e-3);
        CHECK(numeric.torque_Nm == Approx(closed.torque_Nm).epsilon(2e-3));
    }
}

TEST_CASE("physics reference: the helix lag shifts higher slices later", "[physics][reference]") {
    // One flute, 45 deg helix on D 8: the slice at height z sits at phi_tip - z tan(45) / R. With the
    // tip at 0.5 rad and a window [0, 0.1] rad, only z in [(0.5 - 0.1) R, 0.5 R] = [1.6, 2.0] mm cut.
    Cut cut = slot_cut(8, 1, 45, 4, 0.1);
    cut.phi_exit_rad = 0.1;   // a narrow window [0, 0.1]
    const Coefficients edge_only = edge_part(test_coefficients());
    const Forces f = instantaneous_forces(cut, edge_only, 0.5, 4000);
    // 0.4 mm of engaged edge, each mm carrying Fa = Kae.
    CHECK(f.fz_N == Approx(0.4 * edge_only.Kae_N_mm).epsilon(1e-2));
    // Lagging the wrong way would put the engaged slices below z = 0: nothing would cut.
    const Forces before = instantaneous_forces(cut, edge_only, -0.05, 4000);
    CHECK(before.fz_N == 0.0);
}
