// Engine behaviour: OpenCL kernels against their scalar twins, overload flags, spindle stop,
// cancellation, air time.
#include "force_model/engine.hpp"
#include "force_model/engine_fixtures.hpp"

#include <catch2/catch.hpp>

#include <atomic>
#include <cmath>
#include <limits>

using namespace cutload;
using namespace cutload::enginetest;
using force_model::Device;

namespace {

force_model::Prediction run(const motion_io::MotionModel& m, const force_model::RunSpec& s, Device d = Device::Cpu) {
    force_model::PredictOptions o;
    o.device = d;
    return force_model::predict(m, s, o);
}

bool has_flag(const force_model::BlockSummary& b, const std::string& flag) {
    for (const auto& f : b.flags)
        if (f.flag == flag) return true;
    return false;
}

const force_model::BlockSummary& block(const force_model::Prediction& p, const std::string& name) {
    for (const auto& b : p.blocks)
        if (b.block == name) return b;
    FAIL("no block " << name);
    return p.blocks.front();
}

// RMS of the difference of the force traces relative to the RMS force of the reference.
double trace_error(const force_model::Prediction& a, const force_model::Prediction& ref) {
    REQUIRE(a.samples.size() == ref.samples.size());
    double diff = 0, norm = 0;
    for (std::size_t i = 0; i < a.samples.size(); ++i) {
        const auto &x = a.samples[i], &y = ref.samples[i];
        diff += std::pow(x.fx_N - y.fx_N, 2) + std::pow(x.fy_N - y.fy_N, 2) + std::pow(x.fz_N - y.fz_N, 2);
        norm += std::pow(y.fx_N, 2) + std::pow(y.fy_N, 2) + std::pow(y.fz_N, 2);
    }
    REQUIRE(norm > 0);
    return std::sqrt(diff / norm);
}

void compare_devices(const motion_io::MotionModel& m, const force_model::RunSpec& spec) {
    if (!opencl_available()) {
        WARN("no OpenCL device: kernel/twin comparison skipped");
        return;
    }
    const auto cpu = run(m, spec, Device::Cpu);
    const auto cl = run(m, spec, Device::OpenCL);
    CHECK(trace_error(cl, cpu) < 0.005);
    REQUIRE(cl.blocks.size() == cpu.blocks.size());
    for (std::size_t b = 0; b < cpu.blocks.size(); ++b) {
        CHECK(cl.blocks[b].peak_force_N == Approx(cpu.blocks[b].peak_force_N).epsilon(0.005).margin(0.5));
        CHECK(cl.blocks[b].mean_force_N == Approx(cpu.blocks[b].mean_force_N).epsilon(0.005).margin(0.5));
        CHECK(cl.blocks[b].removed_mm3 == Approx(cpu.blocks[b].removed_mm3).epsilon(0.005).margin(0.5));
    }
    CHECK(force_model::stock_volume_mm3(*cl.final_stock) ==
          Approx(force_model::stock_volume_mm3(*cpu.final_stock)).epsilon(1e-4));
}

}  // namespace

TEST_CASE("OpenCL kernels match the scalar twins: straight down-cut") {
    const auto spec = base_spec();
    // Radial depth 1 mm on the y = 0 wall (tool centre at y = -3), axial depth 3 mm.
    compare_devices(legs_motion({-10, -3, 7}, {{{50, -3, 7}, 6000, "N10"}}), spec);
}

TEST_CASE("OpenCL kernels match the scalar twins: corner") {
    const auto spec = base_spec();
    compare_devices(legs_motion({-10, 10, 7}, {{{20, 10, 7}, 3000, "X"}, {{20, 30, 7}, 3000, "Y"}}), spec);
}

TEST_CASE("OpenCL kernels match the scalar twins: ball-end ramp") {
    auto spec = base_spec();
    spec.tool.shape = force_model::ToolShape::Ball;
    spec.tool.corner_radius_mm = 4;
    compare_devices(legs_motion({-6, 10, 11}, {{{30, 10, 7}, 2000, "ramp"}, {{45, 10, 7}, 2000, "level"}}), spec);
}

TEST_CASE("limit flags carry the first time and value") {
    auto spec = base_spec();
    spec.limits = {200, 0.5, 0.2, 0.1, 50};
    const auto m = legs_motion({-10, 10, 7}, {{{50, 10, 7}, 6000, "slot"}});
    const auto p = run(m, spec);
    const auto& b = block(p, "slot");
    for (const char* f : {"force_limit", "torque_limit", "power_limit", "chip_load_limit", "bending_limit"})
        CHECK(has_flag(b, f));
    for (const auto& f : b.flags) {
        CHECK(f.t_s > 0.05);   // the tool reaches the box after 6 mm (60 ms at 100 mm/s)
        CHECK(f.value > 0);
        if (f.flag == "force_limit") CHECK(f.value > 200);
        if (f.flag == "chip_load_limit") CHECK(f.value > 0.1);
    }
    CHECK(b.max_chip_mm == Approx(0.3).epsilon(0.01));   // slot: h peaks at f_t = 6000 / (2 * 10000)
    CHECK(b.peak_force_N > b.mean_force_N);
    CHECK(b.max_axial_engagement_mm == Approx(3).margin(0.11));
    CHECK(b.max_radial_engagement_mm == Approx(8).margin(0.3));
    CHECK_FALSE(has_flag(b, "holder_contact"));
    CHECK_FALSE(has_flag(b, "rapid_in_material"));

    spec.limits = {};
    const auto clean = run(m, spec);
    CHECK(clean.blocks[0].flags.empty());
}

TEST_CASE("holder touching the stock is flagged") {
    auto spec = base_spec(40, 20, 30);
    spec.tool.flute_length_mm = 8;
    spec.tool.stickout_mm = 10;   // holder face 10 mm above the tip, tip 12 mm deep in a 30 mm block
    const auto m = legs_motion({-30, 10, 30.5}, {{{-30, 10, 18}, 3000, "air"}, {{50, 10, 18}, 3000, "deep"}});
    const auto p = run(m, spec);
    CHECK_FALSE(has_flag(block(p, "air"), "holder_contact"));
    CHECK(has_flag(block(p, "deep"), "holder_contact"));
    bool row_flag = false;
    for (const auto& s : p.samples) row_flag |= s.holder_contact;
    CHECK(row_flag);
}

TEST_CASE("a rapid through material is flagged, the same move above the stock is not") {
    const auto spec = base_spec();
    const auto m = legs_motion({-10, 10, 12}, {{{50, 10, 12}, 30000, "G0 above"},
                                               {{50, 10, 8}, 30000, "G0 down"},
                                               {{-10, 10, 8}, 30000, "G0 through"}});
    const auto p = run(m, spec);
    CHECK_FALSE(has_flag(block(p, "G0 above"), "rapid_in_material"));
    CHECK(has_flag(block(p, "G0 through"), "rapid_in_material"));
}

TEST_CASE("spindle stopped in material: flagged, no forces, no NaN") {
    const auto spec = base_spec();
    const auto m = legs_motion({-10, 10, 7}, {{{5, 10, 7}, 3000, "N10", 10000}, {{15, 10, 7}, 3000, "N20", 0}});
    const auto p = run(m, spec);
    CHECK(has_flag(block(p, "N20"), "spindle_stopped"));
    const auto running = run(legs_motion({-10, 10, 7}, {{{5, 10, 7}, 3000, "N10"}, {{15, 10, 7}, 3000, "N20"}}), spec);
    for (const auto& b : running.blocks) CHECK_FALSE(has_flag(b, "spindle_stopped"));
    for (const auto& s : p.samples) {
        CHECK(std::isfinite(s.fx_N));
        CHECK(std::isfinite(s.power_kW));
        if (s.block == 1) CHECK(s.fx_N == 0);
    }
}

TEST_CASE("cancel stops a prediction") {
    const auto spec = base_spec();
    const auto m = legs_motion({-10, 10, 7}, {{{50, 10, 7}, 3000, "N10"}});
    std::atomic<bool> cancel{false};
    force_model::PredictOptions o;
    o.device = Device::Cpu;
    o.cancel = &cancel;
    int calls = 0;
    o.progress = [&](double f) {
        CHECK(f >= 0);
        CHECK(f <= 1);
        if (++calls == 2) cancel = true;
    };
    CHECK_THROWS_AS(force_model::predict(m, spec, o), force_model::Cancelled);
    CHECK(calls == 2);
}

TEST_CASE("air time is written coarsely and costs no angle steps") {
    const auto spec = base_spec();
    // 1 s above the stock, then 0.1 s of cutting.
    const auto m = legs_motion({-50, 10, 20}, {{{-10, 10, 20}, 2400, "air"}, {{-10, 10, 7}, 2400, "down"},
                                               {{0, 10, 7}, 6000, "cut"}});
    const auto p = run(m, spec);
    std::size_t air_rows = 0;
    for (const auto& s : p.samples) air_rows += s.block == 0 ? 1 : 0;
    CHECK(air_rows == 1000);   // one per 1 ms motion sample, not 60 per ms
    CHECK(p.stats.steps < 30000);
    CHECK(block(p, "cut").peak_force_N > 100);
}

TEST_CASE("OpenCL device selection errors are clear") {
    if (opencl_available()) {
        const auto& rt = kernels::OpenClRuntime::instance();
        CHECK_FALSE(rt.device_name().empty());
    } else {
        const auto spec = base_spec();
        const auto m = legs_motion({-10, 10, 7}, {{{0, 10, 7}, 3000, "N10"}});
        CHECK_THROWS_WITH(run(m, spec, Device::OpenCL), Catch::Contains("OpenCL"));
    }
}

TEST_CASE("the rapid threshold comes from the run spec's limits") {
    auto spec = base_spec();
    const auto through = legs_motion({-10, 10, 8}, {{{50, 10, 8}, 30000, "G0 through"}});
    const auto cut = legs_motion({-10, 10, 8}, {{{50, 10, 8}, 6000, "G1 cut"}});
    CHECK_FALSE(has_flag(run(cut, spec).blocks[0], "rapid_in_material"));   // default 20000 mm/min
    // The fixture stops dead at the end of a leg: the Hermite speed overshoots by a third there.
    spec.limits.rapid_feed_mm_min = 60000;
    CHECK_FALSE(has_flag(run(through, spec).blocks[0], "rapid_in_material"));
    spec.limits.rapid_feed_mm_min = 5000;
    const auto p = run(cut, spec);
    const auto& b = p.blocks[0];
    REQUIRE(has_flag(b, "rapid_in_material"));
    for (const auto& f : b.flags)
        if (f.flag == "rapid_in_material") CHECK(f.value == Approx(6000).epsilon(0.01));
}

TEST_CASE("issue 19: a motion model holding NaN or infinity never reaches the engine") {
    const auto spec = base_spec();
    const auto clean = legs_motion({-10, 10, 7}, {{{15, 10, 7}, 3000, "N10"}});
    const double bad[] = {std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity()};
    for (const double v : bad)
        for (int channel = 0; channel < 4; ++channel) {
            auto m = clean;
            std::vector<double>& target = channel == 0 ? m.x_mm : channel == 1 ? m.vz_mm_s : channel == 2 ? m.spindle_rpm
                                                                                                             : m.spindle_angle_deg;
            target[target.size() / 2] = v;
            CHECK_THROWS_WITH(run(m, spec), Catch::Contains("sample " + std::to_string(target.size() / 2)) &&
                                                Catch::Contains("non-finite"));
        }
}
