// A shape the run spec cannot name yet, through the whole engine: a cone cutter (chamfer mill /
// spot drill, 90 deg point) built by cutters/cone.cpp and nothing else, cutting a V-groove. Checked
// against the closed forms of its geometry and of the linear edge-force law on a cone flank:
//
// Flank at theta to the axis, groove depth a, feed per tooth f, N flutes, feed along +X. An edge
// element of the flank at radius r = z tan(theta) has the outward normal (cos theta, -sin theta)
// in (r, z), so its chip is h = f cos(theta) cos(psi) on the front half (psi: angle between the
// element's radial direction and the feed) and nr db = dz. Over a revolution h averages
// f cos(theta) / pi and an element rubs half the time, so the means over whole tooth periods are
//   torque  T  = N [Ktc f a^2 tan(theta) / (2 pi) + Kte a^2 tan(theta) / (4 cos(theta))]
//   axial   Fz = N [sin(theta) (Krc f a / pi + Kre a / (2 cos theta))
//                   + cos(theta) (Kac f a / pi + Kae a / (2 cos theta))]
// (the Ktc term is Ktc times the removal rate over omega: the groove's cross-section a^2 tan(theta)
// swept at f per tooth), the largest chip is f cos(theta), and the groove removed from a box the
// path crosses completely is a prism of cross-section a^2 tan(theta).
//
// Measured (both devices): torque 0.17572 vs 0.17600 N m (-0.16 %: elements at the immersion edges
// carry no edge force below the minimum chip, 2 x 0.0071 / pi of the half turn), Fz 89.549 vs
// 89.784 N (-0.26 %), largest chip 0.070711 mm, groove 120.000 mm3, OpenCL vs scalar 3e-8.
#include "force_model/cutters/shapes.hpp"
#include "force_model/engine.hpp"
#include "force_model/engine_fixtures.hpp"
#include "force_model/reference.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <numbers>
#include <vector>

using namespace cutload;
using namespace cutload::enginetest;

TEST_CASE("engine: a cone cutter cuts the closed-form V-groove with the closed-form torque and thrust", "[engine][cutters]") {
    const double theta = std::numbers::pi / 4, a = 2, f = 0.1, rpm = 10000, box_top = 10;
    const int N = 2;
    const force_model::Cutter cone{force_model::cone_profile(8, 0, 90, 20), N, 30, 30, 32, 40};
    force_model::RunSpec spec = base_spec(30, 20, box_top);
    const force_model::Material& k = spec.material;
    // The groove's centre line lies on a cell boundary (y = 10 with a 0.1 mm grid), so every ray
    // samples the groove's linear flanks at its centre and the dexel cross-section is exact.
    const double feed_mm_min = f * N * rpm, tip_z = box_top - a;
    const motion_io::MotionModel m = legs_motion({-6, 10, tip_z}, {{{36, 10, tip_z}, feed_mm_min, "N10", rpm}});

    const double torque_Nm =
        N * (k.Ktc_N_mm2 * f * a * a * std::tan(theta) / (2 * std::numbers::pi) + k.Kte_N_mm * a * a * std::tan(theta) / (4 * std::cos(theta))) / 1000;
    const double fz_N = N * (std::sin(theta) * (k.Krc_N_mm2 * f * a / std::numbers::pi + k.Kre_N_mm * a / (2 * std::cos(theta))) +
                             std::cos(theta) * (k.Kac_N_mm2 * f * a / std::numbers::pi + k.Kae_N_mm * a / (2 * std::cos(theta))));
    const double groove_mm3 = 30 * a * a * std::tan(theta);
    // Steady: the tool's front half wholly inside the box (tip x from 4 to 26 mm).
    const double speed_mm_s = feed_mm_min / 60, t0_s = (4 + 6) / speed_mm_s, t1_s = (26 + 6) / speed_mm_s;

    std::vector<force_model::Device> devices{force_model::Device::Cpu};
    if (opencl_available()) devices.push_back(force_model::Device::OpenCL);
    std::vector<testref::SteadyMean> means;
    for (const force_model::Device d : devices) {
        force_model::PredictOptions opt;
        opt.device = d;
        const force_model::Prediction p = force_model::predict_with_cutter(m, spec, cone, opt, force_model::EngineSettings{});
        const testref::SteadyMean mean = testref::steady_mean(p.samples, t0_s, t1_s, N);
        double max_chip_mm = 0;
        for (const auto& s : p.samples)
            if (s.t_s >= t0_s && s.t_s <= t1_s) max_chip_mm = std::max(max_chip_mm, double(s.chip_mm));
        const double removed_mm3 = 30 * 20 * box_top - force_model::stock_volume_mm3(*p.final_stock);
        INFO(testref::device_name(d) << ": torque " << mean.forces.torque_Nm << " vs " << torque_Nm << " N m, Fz "
                                     << mean.forces.fz_N << " vs " << fz_N << " N, max chip " << max_chip_mm
                                     << " mm, removed " << removed_mm3 << " vs " << groove_mm3 << " mm3, "
                                     << mean.tooth_periods << " tooth periods");
        REQUIRE(mean.tooth_periods >= 100);
        CHECK(mean.forces.torque_Nm == Approx(torque_Nm).epsilon(0.01));
        CHECK(mean.forces.fz_N == Approx(fz_N).epsilon(0.01));
        CHECK(max_chip_mm == Approx(f * std::cos(theta)).epsilon(0.01));
        CHECK(removed_mm3 == Approx(groove_mm3).epsilon(1e-3));
        // The cross-section at x = 15: each ray keeps material up to the flank, a - |y - 10| below
        // the top within the groove.
        const force_model::Stock& st = *p.final_stock;
        for (int j = 70; j < 130; ++j) {
            const double y = (j + 0.5) * 0.1, depth = std::max(0.0, a - std::abs(y - 10));
            INFO("ray j " << j);
            CHECK(kernels::ray_top(st.ray(150, j)) == Approx(box_top - depth).margin(1e-4));
        }
        means.push_back(mean);
    }
    if (means.size() == 2) {
        CHECK(testref::relative_force_error(means[1].forces, means[0].forces) < 0.005);
        CHECK(means[1].forces.torque_Nm == Approx(means[0].forces.torque_Nm).epsilon(0.005));
    }
}
