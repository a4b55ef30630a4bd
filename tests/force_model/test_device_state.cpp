// Device state kept across predictions (kernels::OpenClRuntime's pool): a later prediction in the
// process borrows the first one's queue, kernels and buffers, creates none, and gives the same
// result; a prediction told that nobody wants its final stock returns none and the same rows.
#include "engine_fixtures.hpp"
#include "force_model/stock.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>

using namespace cutload;
using namespace cutload::enginetest;

namespace {

motion_io::MotionModel two_passes() {
    // A slot across the block, then a pass beside it that re-cuts its wall.
    return legs_motion({-6, 6, 7}, {{{46, 6, 7}, 3000, "N10"}, {{46, 12, 7}, 3000, "N20"}, {{-6, 12, 7}, 3000, "N30"}});
}

bool same_rows(const force_model::Prediction& a, const force_model::Prediction& b) {
    if (a.samples.size() != b.samples.size()) return false;
    for (std::size_t i = 0; i < a.samples.size(); ++i) {
        const auto &x = a.samples[i], &y = b.samples[i];
        if (x.t_s != y.t_s || x.fx_N != y.fx_N || x.fy_N != y.fy_N || x.fz_N != y.fz_N || x.removed_mm3 != y.removed_mm3)
            return false;
    }
    return true;
}

}  // namespace

TEST_CASE("a second OpenCL prediction in the process creates no queue, kernel or buffer and gives the same rows",
          "[engine][opencl][device_state]") {
    if (!opencl_available()) {
        WARN("no OpenCL device: nothing to pool");
        return;
    }
    const auto spec = base_spec();
    const auto m = two_passes();
    const force_model::Prediction first = run_on(m, spec, force_model::Device::OpenCL);
    const kernels::PoolStats after_first = kernels::OpenClRuntime::instance().pool_stats();
    REQUIRE(after_first.queues_created == 1);
    REQUIRE(after_first.kernels_created == 3);
    REQUIRE(after_first.buffers_created > 0);
    REQUIRE(first.samples.size() > 1000);

    const force_model::Prediction second = run_on(m, spec, force_model::Device::OpenCL);
    const kernels::PoolStats after_second = kernels::OpenClRuntime::instance().pool_stats();
    CHECK(after_second.queues_created == after_first.queues_created);
    CHECK(after_second.kernels_created == after_first.kernels_created);
    CHECK(after_second.buffers_created == after_first.buffers_created);
    CHECK(after_second.reused - after_first.reused == after_second.leases - after_first.leases);
    CHECK(same_rows(first, second));
    REQUIRE(first.final_stock);
    REQUIRE(second.final_stock);
    CHECK(force_model::save_stock_bytes(*first.final_stock) == force_model::save_stock_bytes(*second.final_stock));

    // A run from the first one's stock borrows the same objects too (its stock is copied up, not filled).
    const force_model::Prediction chained = run_on(m, spec, force_model::Device::OpenCL, first.final_stock.get());
    CHECK(kernels::OpenClRuntime::instance().pool_stats().buffers_created == after_first.buffers_created);
    const force_model::Prediction chained_cpu = run_on(m, spec, force_model::Device::Cpu, first.final_stock.get());
    // The second pass over cut stock: only the air and the re-cut wall are left.
    REQUIRE(chained.samples.size() == chained_cpu.samples.size());
    double removed_cl = 0, removed_cpu = 0;
    for (const auto& s : chained.samples) removed_cl += s.removed_mm3;
    for (const auto& s : chained_cpu.samples) removed_cpu += s.removed_mm3;
    CHECK(removed_cl == Approx(removed_cpu).margin(0.5));
}

TEST_CASE("a prediction that does not keep its final stock returns none and the same rows",
          "[engine][device_state]") {
    const auto spec = base_spec();
    const auto m = two_passes();
    for (const force_model::Device d : {force_model::Device::Cpu, force_model::Device::OpenCL}) {
        if (d == force_model::Device::OpenCL && !opencl_available()) {
            WARN("no OpenCL device: the CPU path only");
            continue;
        }
        force_model::PredictOptions o;
        o.device = d;
        const force_model::Prediction kept = force_model::predict(m, spec, o);
        o.keep_final_stock = false;
        const force_model::Prediction dropped = force_model::predict(m, spec, o);
        REQUIRE(kept.final_stock);
        CHECK_FALSE(dropped.final_stock);
        CHECK(same_rows(kept, dropped));
        REQUIRE(kept.blocks.size() == dropped.blocks.size());
        for (std::size_t b = 0; b < kept.blocks.size(); ++b) {
            CHECK(kept.blocks[b].peak_force_N == dropped.blocks[b].peak_force_N);
            CHECK(kept.blocks[b].removed_mm3 == dropped.blocks[b].removed_mm3);
        }
    }
}

TEST_CASE("a CPU device that reads wrapped host arrays in place is told apart, and its steps then queue no write",
          "[engine][opencl][device_state]") {
    if (!opencl_available()) {
        WARN("no OpenCL device: nothing to ask");
        return;
    }
    kernels::OpenClRuntime& rt = kernels::OpenClRuntime::instance();
    const bool in_place = rt.wraps_host_arrays_in_place();
    CHECK(rt.wraps_host_arrays_in_place() == in_place);   // asked once, the same answer after
    // Only a device that shares the host's memory can read the host's arrays where they lie.
    if (!rt.host_unified_memory()) CHECK_FALSE(in_place);
    // PoCL's CPU device does (its buffers over host arrays are those arrays): the suite's device
    // then runs the in-place path, and tests/cli/test_device_state_cli.cpp holds its forces to the
    // written path's (CUTLOAD_OPENCL_DISCRETE=1) byte for byte.
    if (rt.host_unified_memory() && rt.device_name().find("pthread") != std::string::npos) CHECK(in_place);
    // Two predictions with batches of different sizes (the array grows) give the twins' rows.
    const auto spec = base_spec();
    const auto m = two_passes();
    const force_model::Prediction cl = run_on(m, spec, force_model::Device::OpenCL);
    const force_model::Prediction again = run_on(m, spec, force_model::Device::OpenCL);
    CHECK(same_rows(cl, again));
    const force_model::Prediction twin = run_on(m, spec, force_model::Device::Cpu);
    REQUIRE(cl.samples.size() == twin.samples.size());
    double peak_cl = 0, peak_twin = 0;
    for (std::size_t i = 0; i < cl.samples.size(); ++i) {
        peak_cl = std::max(peak_cl, double(std::abs(cl.samples[i].fx_N)));
        peak_twin = std::max(peak_twin, double(std::abs(twin.samples[i].fx_N)));
    }
    CHECK(peak_twin > 10);
    CHECK(peak_cl == Approx(peak_twin).epsilon(0.005));
}
