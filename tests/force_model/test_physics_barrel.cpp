// A barrel tool (document 003) in a three-axis side cut with its axis vertical, the engaged edge on
// the large flank arc, against a numerical integration written here from the mechanistic model
// (Altintas, Manufacturing Automation, 2nd ed., ch. 2, with the general end mill's edge geometry),
// not from the engine.
//
// The tool: widest radius r at height z_b above the tip, flank arc of radius r1 centred across
// the axis at (r - r1, z_b). At height z below z_b the arc is at
//   r(z) = r - r1 + sqrt(r1^2 - (z_b - z)^2),
// and its outward normal in the (r, z) plane is (sin k, -cos k) with cos k = (z_b - z) / r1: the
// surface faces down by the angle b = asin((z_b - z) / r1) from the horizontal, like a taper of
// half angle b that changes with height. Per unit height:
//   edge length   db = dz / cos(b)
//   chip          h  = c sin(phi) cos(b)      (the feed per tooth's component along the normal)
//   Ft, Fr, Fa    = (K.c h + K.e) / cos(b)
// Fr pushes the tool along the inward normal and Fa along the edge (upward), so on the tool, with u
// the radial unit vector (sin phi, cos phi) of a cutting point (the reference.hpp convention):
//   horizontal   (-Fr cos(b) + Fa sin(b)) u + Ft (-cos phi, sin phi)
//   axial        Fz = Fr sin(b) + Fa cos(b)
//   torque       T = r(z) Ft
// The cut: the tool's tip hangs below the stock, whose top is level with the widest point and
// whose bottom is `axial_mm` below it, and a box face parallel to the feed at d = r - ae from the
// axis. At height z the disc's immersion window is [0, acos(d / r(z))] in up milling and
// [acos(-d / r(z)), pi] in down milling (no window where r(z) <= d). The mean over whole
// revolutions is N / (2 pi) times the integral over the band and the window, which no helix
// changes (each disc only shifts in phase), evaluated by the midpoint rule.
#include "force_model/reference.hpp"

#include <catch2/catch.hpp>
#include <fmt/format.h>

#include <cmath>
#include <numbers>
#include <string>

using namespace cutload;
using namespace cutload::testref;

namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kRpm = 10000;
constexpr double kGridMm = 0.02;

// Document 003's tool by default: r 3, r1 96, r2 1 mm.
struct BarrelCut {
    double diameter_mm = 6, barrel_radius_mm = 96, tip_radius_mm = 1;
    double axial_mm = 8, feed_per_tooth_mm = 0.08, radial_at_widest_mm = 1.2;
    int flutes = 2;
    bool up = true;
};

// The widest point's height, from the tangency of the arc with the tip ball (written out here
// rather than taken from the engine's header): |centre of arc - centre of ball| = r1 - r2.
double widest_height_mm(const BarrelCut& c) {
    const double r = c.diameter_mm / 2, r1 = c.barrel_radius_mm, r2 = c.tip_radius_mm;
    const double dr = r1 - r, dc = r1 - r2;
    return r2 + std::sqrt(dc * dc - dr * dr);
}

Forces barrel_reference(const BarrelCut& c, const Coefficients& k, int z_steps = 800, int phi_steps = 2000) {
    const double r_widest = c.diameter_mm / 2, r1 = c.barrel_radius_mm, d = r_widest - c.radial_at_widest_mm;
    const double dz = c.axial_mm / z_steps;
    Forces sum;
    for (int iz = 0; iz < z_steps; ++iz) {
        const double below = c.axial_mm - (iz + 0.5) * dz;   // z_b - z
        const double sb = below / r1, cb = std::sqrt(1 - sb * sb);
        const double r = r_widest - r1 + r1 * cb;
        if (r <= d) continue;
        add_flank_slice(sum, k, r, d, sb, cb, c.up, c.feed_per_tooth_mm, dz, phi_steps);
    }
    const double scale = c.flutes / (2 * kPi);
    return {scale * sum.fx_N, scale * sum.fy_N, scale * sum.fz_N, scale * sum.torque_Nm};
}

// The flat end mill of the barrel's widest diameter in the same cut (Altintas' closed form).
Cut flat_equivalent(const BarrelCut& c) {
    return c.up ? up_cut(c.diameter_mm, c.flutes, 30, c.axial_mm, c.feed_per_tooth_mm, c.radial_at_widest_mm)
                : down_cut(c.diameter_mm, c.flutes, 30, c.axial_mm, c.feed_per_tooth_mm, c.radial_at_widest_mm);
}

struct EngineMean {
    Forces forces;
    int tooth_periods = 0;
};

// The engine's steady mean for the barrel cut on one device: the flat cut's box and path, with the
// box's bottom raised to the band and the path lowered so that the widest point is level with the
// box's top (the tip and the ball hang below the stock, in the air).
EngineMean engine_mean(const BarrelCut& c, const Coefficients& k, force_model::Device device) {
    const Cut base = flat_equivalent(c);
    StraightSetup setup = straight_setup(base, kRpm);
    const double top_mm = setup.box.max_mm[2], z_b = widest_height_mm(c);
    setup.box.min_mm[2] = top_mm - c.axial_mm;
    setup.path.start_mm[2] = top_mm - z_b;
    for (PathSegment& s : setup.path.segments) s.end_mm[2] = top_mm - z_b;
    const motion_io::MotionModel motion = uniform_motion(setup.path);
    force_model::RunSpec spec = flat_tool_spec(base, k, setup.box, kGridMm);
    spec.tool.shape = force_model::ToolShape::Barrel;
    spec.tool.barrel_radius_mm = c.barrel_radius_mm;
    spec.tool.tip_radius_mm = c.tip_radius_mm;
    // The flutes go on 2 mm above the widest point as a cylinder, in the air above the stock.
    spec.tool.flute_length_mm = z_b + 2;
    spec.tool.stickout_mm = z_b + 12;
    force_model::PredictOptions opt;
    opt.device = device;
    const force_model::Prediction p = force_model::predict(motion, spec, opt);
    const SteadyMean m = steady_mean(p.samples, setup.steady_t0_s, setup.steady_t1_s, c.flutes);
    return {m.forces, m.tooth_periods};
}

void check_barrel_cut(const BarrelCut& c) {
    const Coefficients k = test_coefficients();
    const Forces expected = barrel_reference(c, k);
    // The integration itself: a finer grid changes nothing ...
    REQUIRE(relative_force_error(barrel_reference(c, k, 1600, 4000), expected) < 1e-5);
    // ... and the barrel matters here by more than the tolerance, so the check below can fail.
    const double barrel_effect = relative_force_error(average_forces(flat_equivalent(c), k), expected);
    REQUIRE(barrel_effect > 0.04);

    for (force_model::Device device : devices_under_test()) {
        const EngineMean m = engine_mean(c, k, device);
        const double mean_err = relative_force_error(m.forces, expected);
        const double torque_err = std::abs(m.forces.torque_Nm / expected.torque_Nm - 1);
        const double fz_err = std::abs(m.forces.fz_N / expected.fz_N - 1);
        const std::string figures = fmt::format(
            "{} barrel r {} r1 {} r2 {} {} milling a{} ae{} c{}: mean F ({:.3f},{:.3f},{:.3f}) N vs reference "
            "({:.3f},{:.3f},{:.3f}) err {:.3f}% (Fz {:.3f}%); torque {:.4f} vs {:.4f} N m err {:.3f}%; flat end mill "
            "differs by {:.1f}%; {} periods",
            device_name(device), c.diameter_mm / 2, c.barrel_radius_mm, c.tip_radius_mm, c.up ? "up" : "down",
            c.axial_mm, c.radial_at_widest_mm, c.feed_per_tooth_mm, m.forces.fx_N, m.forces.fy_N, m.forces.fz_N,
            expected.fx_N, expected.fy_N, expected.fz_N, 100 * mean_err, 100 * fz_err, m.forces.torque_Nm,
            expected.torque_Nm, 100 * torque_err, 100 * barrel_effect, m.tooth_periods);
        report_figure(figures);
        INFO(figures);
        REQUIRE(m.tooth_periods >= 10);
        CHECK(mean_err < 0.01);
        CHECK(torque_err < 0.01);
        CHECK(fz_err < 0.01);
    }
}

}  // namespace

TEST_CASE("physics: a barrel tool's up-milling side cut on its flank arc matches the numerical integration",
          "[physics][barrel]") {
    check_barrel_cut(BarrelCut{});
}

TEST_CASE("physics: a barrel tool's down-milling side cut on its flank arc matches the numerical integration",
          "[physics][barrel]") {
    BarrelCut c;
    c.up = false;
    check_barrel_cut(c);
}

TEST_CASE("physics: as the barrel radius grows, the barrel's side cut tends to the flat end mill's",
          "[physics][barrel]") {
    const Coefficients k = test_coefficients();
    for (bool up : {true, false}) {
        BarrelCut c;
        c.up = up;
        const Forces flat = average_forces(flat_equivalent(c), k);
        // The integration: the arc's sag over the band is a^2 / (2 r1), so the gap to the flat end
        // mill shrinks as 1 / r1 (ten times the radius, about a tenth of the gap).
        double last_gap = 1;
        std::string gaps;
        for (double r1 : {1e2, 1e3, 1e4, 1e5}) {
            c.barrel_radius_mm = r1;
            const double gap = relative_force_error(barrel_reference(c, k), flat);
            gaps += fmt::format(" r1 {:g} mm: {:.4f}%;", r1, 100 * gap);
            INFO("r1 " << r1 << " mm: " << 100 * gap << "% from the flat end mill");
            CHECK(gap < 0.2 * last_gap);
            last_gap = gap;
        }
        report_figure(fmt::format("{} milling, integration against the flat end mill's closed form:{}",
                                  up ? "up" : "down", gaps));
        CHECK(last_gap < 1e-3);
        // The engine, with a barrel of 2 m radius (its widest point 90.4 mm above the tip): the flat
        // end mill's closed form within 1 %.
        c.barrel_radius_mm = 2000;
        for (force_model::Device device : devices_under_test()) {
            const EngineMean m = engine_mean(c, k, device);
            const double err = relative_force_error(m.forces, flat);
            const double torque_err = std::abs(m.forces.torque_Nm / flat.torque_Nm - 1);
            const std::string figures =
                fmt::format("{} barrel r1 2000 mm {} milling: err {:.3f}% (torque {:.3f}%) against the flat end "
                            "mill's closed form, {:.3f}% between the integration and the closed form",
                            device_name(device), up ? "up" : "down", 100 * err, 100 * torque_err,
                            100 * relative_force_error(barrel_reference(c, k), flat));
            report_figure(figures);
            INFO(figures);
            REQUIRE(m.tooth_periods >= 10);
            CHECK(err < 0.01);
            CHECK(torque_err < 0.01);
        }
    }
}
