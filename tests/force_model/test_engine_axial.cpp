// Axial accuracy: the engaged length of an edge element follows the dexel interval ends, so forces
// track axial depths that are not multiples of axial_step_mm (physics finding 2: a +-0.01 mm change
// used to leave forces unchanged, and 2.95 mm cut like 2.9 mm).
#include "force_model/engine.hpp"
#include "force_model/engine_fixtures.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <vector>

using namespace cutload;
using namespace cutload::enginetest;
using force_model::Device;

namespace {

struct MeanForces {
    double fx_N = 0, fy_N = 0, fz_N = 0, torque_Nm = 0;
    double max_axial_mm = 0;
};

// Down-cut of radial depth 2 mm along the y = 0 wall of the 40 x 20 x 10 box, tip `depth_mm` below
// the top. Mean over whole tooth periods (90 rows of 2 deg for 2 flutes) of the steady part, where
// the tool centre runs from x = 10 to x = 28 mm.
MeanForces side_cut_mean(double depth_mm, Device device) {
    const auto spec = base_spec();
    const double z = 10 - depth_mm;
    const auto m = legs_motion({-10, -2, z}, {{{30, -2, z}, 6000, "N10"}});
    force_model::PredictOptions o;
    o.device = device;
    const auto p = force_model::predict(m, spec, o);
    std::vector<const force_model::ForceSample*> steady;
    for (const auto& s : p.samples)
        if (s.t_s >= 0.2 && s.t_s <= 0.38) steady.push_back(&s);
    const std::size_t rows_per_period = 90;
    REQUIRE(steady.size() >= 10 * rows_per_period);
    const std::size_t n = steady.size() / rows_per_period * rows_per_period;
    MeanForces mean;
    for (std::size_t k = 0; k < n; ++k) {
        mean.fx_N += steady[k]->fx_N / double(n);
        mean.fy_N += steady[k]->fy_N / double(n);
        mean.fz_N += steady[k]->fz_N / double(n);
        mean.torque_Nm += steady[k]->torque_Nm / double(n);
        mean.max_axial_mm = std::max(mean.max_axial_mm, double(steady[k]->axial_engagement_mm));
    }
    return mean;
}

double vector_error(const MeanForces& a, const MeanForces& b) {
    return std::sqrt(std::pow(a.fx_N - b.fx_N, 2) + std::pow(a.fy_N - b.fy_N, 2) + std::pow(a.fz_N - b.fz_N, 2)) /
           std::sqrt(b.fx_N * b.fx_N + b.fy_N * b.fy_N + b.fz_N * b.fz_N);
}

MeanForces scaled(const MeanForces& f, double s) {
    return {f.fx_N * s, f.fy_N * s, f.fz_N * s, f.torque_Nm * s, f.max_axial_mm * s};
}

}  // namespace

TEST_CASE("forces follow axial depths that are not multiples of the axial step") {
    std::vector<Device> devices{Device::Cpu};
    if (opencl_available()) devices.push_back(Device::OpenCL);
    else WARN("no OpenCL device: axial depth test runs on the CPU path only");
    std::vector<MeanForces> at_3mm;
    for (Device device : devices) {
        // Altintas' closed-form average of a flat end mill (chip-area and edge terms alike) is
        // proportional to the axial depth, so the closed-form ratio between two depths is a / 3.
        const MeanForces ref = side_cut_mean(3.0, device);
        at_3mm.push_back(ref);
        CHECK(ref.max_axial_mm == Approx(3.0).margin(1e-3));
        for (double depth_mm : {2.95, 3.01, 3.05}) {
            const MeanForces f = side_cut_mean(depth_mm, device);
            const MeanForces expected = scaled(ref, depth_mm / 3.0);
            INFO((device == Device::Cpu ? "cpu" : "opencl")
                 << " depth " << depth_mm << " mm: F (" << f.fx_N << ", " << f.fy_N << ", " << f.fz_N
                 << ") N, expected (" << expected.fx_N << ", " << expected.fy_N << ", " << expected.fz_N << ") N");
            CHECK(vector_error(f, expected) < 0.003);
            CHECK(f.torque_Nm == Approx(expected.torque_Nm).epsilon(0.003));
            CHECK(f.max_axial_mm == Approx(depth_mm).margin(1e-3));
        }
    }
    if (at_3mm.size() == 2) CHECK(vector_error(at_3mm[1], at_3mm[0]) < 0.005);
}
