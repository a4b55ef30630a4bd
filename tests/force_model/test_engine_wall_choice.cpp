// Sub-cell walls of two sweeps at different heights: a higher pass whose side takes the cell centres
// in deeper than a lower slot's must not make the stock forget the lower slot's wall. Each ray keeps
// the deepest wall and, besides it, the lowest one (docs/force_model.md, "Sub-cell walls"). With
// the deepest wall alone, the points of a re-cut of the lower slot below the higher pass fell back
// to the cell-centre test and cut (demo N480/N520: 66 to 68 N of re-cut force).
#include "force_model/engine.hpp"
#include "force_model/engine_fixtures.hpp"

#include <catch2/catch.hpp>

#include <cmath>

using namespace cutload;
using force_model::Device;
using enginetest::load_between;
using enginetest::Load;

namespace {

// A slot along +x through a 60 x 60 x 10 mm box at tip height z_mm, centred on y_mm.
motion_io::MotionModel slot(double y_mm, double z_mm, double feed_mm_min) {
    return enginetest::legs_motion({-15, y_mm, z_mm}, {{{75, y_mm, z_mm}, feed_mm_min, "slot"}});
}

std::vector<Device> devices() {
    if (enginetest::opencl_available()) return {Device::Cpu, Device::OpenCL};
    WARN("no OpenCL device: the kernel path is not tested here");
    return {Device::Cpu};
}

}  // namespace

TEST_CASE("a higher pass that takes the walls' cells in deeper keeps the lower slot's wall") {
    const auto spec = enginetest::base_spec(60, 60, 10);   // grid 0.1 mm
    const double feed_mm_min = 3000, speed_mm_s = feed_mm_min / 60;
    // The middle 30 mm of the 90 mm moves: full slotting, away from the box's faces.
    const double t0 = 30 / speed_mm_s, t1 = 60 / speed_mm_s;
    // The lower slot's walls lie 0.03 mm off the cell boundaries; the higher pass runs 0.05 mm
    // further to +y, so along the +y wall its side is the deeper one for every ray.
    const auto lower = slot(30.03, 4, feed_mm_min);
    const auto higher = slot(30.08, 7, feed_mm_min);
    for (Device d : devices()) {
        for (bool lower_first : {true, false}) {
            // Lower slot then higher pass, and the other way round (the demo's pocket: Z27 ring,
            // then Z24); then the lower slot again from the final stock.
            const auto a = enginetest::run_on(lower_first ? lower : higher, spec, d);
            const auto b = enginetest::run_on(lower_first ? higher : lower, spec, d, a.final_stock.get());
            const auto again = enginetest::run_on(lower, spec, d, b.final_stock.get());
            const Load cut = load_between(lower_first ? a : b, t0, t1), re = load_between(again, t0, t1);
            INFO((d == Device::Cpu ? "cpu" : "opencl") << (lower_first ? ", lower slot first" : ", higher pass first")
                                                         << ": slot mean " << cut.mean_N << " peak " << cut.peak_N
                                                         << " N; re-cut mean " << re.mean_N << " peak " << re.peak_N
                                                         << " N");
            REQUIRE(cut.mean_N > 300);
            // Measured: 0 N with two walls per ray; with the deepest wall alone, mean 5.1 N and
            // peak 40.5 N (docs/force_model.md, "Two walls per ray").
            CHECK(re.mean_N < 0.002 * cut.mean_N);
            CHECK(re.peak_N < 0.02 * cut.peak_N);
        }
    }
}

TEST_CASE("lower walls: OpenCL kernels match the scalar twins on a re-cut below a deeper higher pass") {
    if (!enginetest::opencl_available()) {
        WARN("no OpenCL device: kernel/twin comparison skipped");
        return;
    }
    const auto spec = enginetest::base_spec(60, 60, 10);
    const auto lower = slot(30.03, 4, 3000);
    const auto higher = slot(30.08, 7, 3000);
    double peak_N[2] = {0, 0}, walls[2] = {0, 0};
    int k = 0;
    for (Device d : {Device::Cpu, Device::OpenCL}) {
        const auto a = enginetest::run_on(higher, spec, d);
        const auto b = enginetest::run_on(lower, spec, d, a.final_stock.get());
        // A pass 0.5 mm inside the +y wall at the lower height: a real finishing cut that sees the
        // walls, to compare the two paths on something that is not zero.
        const auto finish = enginetest::run_on(slot(30.53, 4, 3000), spec, d, b.final_stock.get());
        for (const auto& s : finish.samples) peak_N[k] = std::max(peak_N[k], double(std::hypot(s.fx_N, s.fy_N)));
        walls[k] = b.final_stock ? 1 : 0;
        ++k;
    }
    INFO("finishing pass peak |Fxy|: cpu " << peak_N[0] << " N, opencl " << peak_N[1] << " N");
    REQUIRE(walls[0] == 1);
    REQUIRE(walls[1] == 1);
    REQUIRE(peak_N[0] > 50);
    CHECK(peak_N[1] == Approx(peak_N[0]).epsilon(0.005));
}
