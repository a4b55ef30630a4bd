// Tapered flat end mills in side cuts: predict() against a numerical integration written from the
// mechanistic model's formulas (Altintas, Manufacturing Automation, 2nd ed., ch. 2, with the
// general end mill's edge geometry), not from the engine.
//
// The tool: tip radius R0, flank at beta to the axis, so at height z above the tip the cutting
// radius is r(z) = R0 + z tan(beta). The flank's outward normal in the (r, z) plane is
// (cos beta, -sin beta) and its edge runs along (sin beta, cos beta). Per unit height:
//   edge length   db = dz / cos(beta)
//   chip          h  = c sin(phi) cos(beta)      (the feed per tooth's component along the normal)
//   Ft, Fr, Fa    = (K.c h + K.e) / cos(beta)    (Altintas' linear edge-force law per unit edge)
// Fr pushes the tool along the inward normal and Fa along the edge, so on the tool, with u the
// radial unit vector (sin phi, cos phi) of a cutting point (the reference.hpp convention):
//   horizontal   (-Fr cos(beta) + Fa sin(beta)) u + Ft (-cos phi, sin phi)
//   axial        Fz = Fr sin(beta) + Fa cos(beta)
//   torque       T = r(z) Ft
// A straight side cut into a box face parallel to the feed at distance d from the axis: at height z
// the disc's immersion window is [0, acos(d / r)] in up milling and [acos(-d / r), pi] in down
// milling (the radial depth grows with r). The mean over whole revolutions is
//   N / (2 pi) * integral over z in [0, a] and phi in the window,
// which no helix changes (each disc only shifts in phase), evaluated by the midpoint rule.
#include "force_model/reference.hpp"

#include <catch2/catch.hpp>
#include <fmt/format.h>

#include <cmath>
#include <numbers>
#include <vector>

using namespace cutload;
using namespace cutload::testref;

namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kRpm = 10000;
constexpr double kGridMm = 0.02;

struct TaperCut {
    double tip_diameter_mm = 8, taper_deg = 5, axial_mm = 5, feed_per_tooth_mm = 0.1, radial_at_tip_mm = 2;
    int flutes = 2;
    bool up = true;
};

Forces taper_reference(const TaperCut& c, const Coefficients& k, int z_steps = 800, int phi_steps = 2000) {
    const double beta = c.taper_deg * kPi / 180, cb = std::cos(beta), sb = std::sin(beta);
    const double R0 = c.tip_diameter_mm / 2, d = R0 - c.radial_at_tip_mm;   // box face from the axis
    const double dz = c.axial_mm / z_steps;
    Forces sum;
    for (int iz = 0; iz < z_steps; ++iz) {
        const double z = (iz + 0.5) * dz, r = R0 + z * std::tan(beta);
        add_flank_slice(sum, k, r, d, sb, cb, c.up, c.feed_per_tooth_mm, dz, phi_steps);
    }
    const double scale = c.flutes / (2 * kPi);
    return {scale * sum.fx_N, scale * sum.fy_N, scale * sum.fz_N, scale * sum.torque_Nm};
}

Cut untapered(const TaperCut& c) {
    return c.up ? up_cut(c.tip_diameter_mm, c.flutes, 30, c.axial_mm, c.feed_per_tooth_mm, c.radial_at_tip_mm)
                : down_cut(c.tip_diameter_mm, c.flutes, 30, c.axial_mm, c.feed_per_tooth_mm, c.radial_at_tip_mm);
}

void check_taper_cut(const TaperCut& c) {
    const Coefficients k = test_coefficients();
    // The box and path of the untapered cut with the same tip: the face stays at R0 - ae0 from the
    // axis, so the tapered flank's radial depth grows with height.
    const Cut base = untapered(c);
    const StraightSetup setup = straight_setup(base, kRpm);
    const motion_io::MotionModel motion = uniform_motion(setup.path);
    force_model::RunSpec spec = flat_tool_spec(base, k, setup.box, kGridMm);
    spec.tool.taper_deg = c.taper_deg;
    const Forces expected = taper_reference(c, k);

    // The integration itself: taper 0 gives Altintas' closed form, and a finer grid changes nothing.
    TaperCut flat = c;
    flat.taper_deg = 0;
    REQUIRE(relative_force_error(taper_reference(flat, k), average_forces(base, k)) < 1e-5);
    REQUIRE(relative_force_error(taper_reference(c, k, 1600, 4000), expected) < 1e-5);
    // ... and the taper matters here by more than the tolerance, so the check below can fail.
    const double taper_effect = relative_force_error(average_forces(base, k), expected);
    REQUIRE(taper_effect > 0.04);

    for (force_model::Device device : devices_under_test()) {
        force_model::PredictOptions opt;
        opt.device = device;
        const force_model::Prediction p = force_model::predict(motion, spec, opt);
        const SteadyMean m = steady_mean(p.samples, setup.steady_t0_s, setup.steady_t1_s, c.flutes);
        const double mean_err = relative_force_error(m.forces, expected);
        const double torque_err = std::abs(m.forces.torque_Nm / expected.torque_Nm - 1);
        const std::string figures = fmt::format(
            "{} taper {} deg {} milling D{} a{} ae{} c{}: mean F ({:.3f},{:.3f},{:.3f}) N vs reference "
            "({:.3f},{:.3f},{:.3f}) err {:.3f}%; torque {:.4f} vs {:.4f} N m err {:.3f}%; untapered closed form "
            "differs by {:.1f}%; {} periods",
            device_name(device), c.taper_deg, c.up ? "up" : "down", c.tip_diameter_mm, c.axial_mm, c.radial_at_tip_mm,
            c.feed_per_tooth_mm, m.forces.fx_N, m.forces.fy_N, m.forces.fz_N, expected.fx_N, expected.fy_N,
            expected.fz_N, 100 * mean_err, m.forces.torque_Nm, expected.torque_Nm, 100 * torque_err,
            100 * taper_effect, m.tooth_periods);
        report_figure(figures);
        INFO(figures);
        REQUIRE(m.tooth_periods >= 10);
        CHECK(mean_err < 0.02);
        CHECK(torque_err < 0.02);
        CHECK(std::abs(m.forces.fz_N / expected.fz_N - 1) < 0.02);
    }
}

}  // namespace

TEST_CASE("physics: a tapered flat end mill's up-milling side cut matches the numerical integration",
          "[physics][taper]") {
    check_taper_cut(TaperCut{});
}

TEST_CASE("physics: a tapered flat end mill's down-milling side cut matches the numerical integration",
          "[physics][taper]") {
    TaperCut c;
    c.up = false;
    check_taper_cut(c);
}
