// The backend's fences (Backend::fence, wait_for), on which the driver's two-slot pipeline rests:
// a batch's engagement is queued before the batch before it is completed, and the host then reads
// that older batch's results after waiting for its fence alone. Checked on the backends
// themselves, three batches along a slot, each engaged then swept:
// - after wait_for(the older batch's fence), with the newer batch still queued, the older one's
//   results are all written (they start as NaN);
// - every result, engagement and removal, equals bit for bit the same calls made one at a time
//   with a full wait after each: the device runs the same commands in the same order.
// The OpenCL backend only: the scalar one runs each call as it is made (its fences are 0). A wait
// that did not wait, or one staging set for both batches, fails these checks (tried).
#include "engine/setup.hpp"
#include "engine_fixtures.hpp"

#include <cmath>
#include <limits>
#include <numbers>

using namespace cutload;
using namespace cutload::enginetest;

namespace {

constexpr int kBatches = 3;
constexpr std::size_t kStepsPerBatch = 1500;   // 2 deg steps at 10000 rpm, 3000 mm/min: 2.5 mm of slot

struct Calls {
    std::vector<kernels::StepBatch> batches;
    std::vector<std::vector<kernels::SweepSegment>> segs;
    std::vector<std::vector<kernels::SweepCall>> calls;
};

// A slot along x at y = 10, 3 mm deep in the fixture's 40 x 20 x 10 block, from x = 8 on.
Calls slot_calls(const force_model::Stock& stock, double radius_mm) {
    Calls c;
    const double rpm = 10000, feed_mm_min = 3000, step_deg = 2;
    const double dx_per_step_mm = feed_mm_min / 60 * (step_deg / (6 * rpm));
    const double feed_per_tooth_mm = feed_mm_min / (rpm * 2);
    const double y = 10, z = 7;
    const auto& g = stock.grid;
    for (int b = 0; b < kBatches; ++b) {
        kernels::StepBatch s;
        s.spin = 1;
        for (std::size_t k = 0; k < kStepsPerBatch; ++k) {
            const std::size_t step = std::size_t(b) * kStepsPerBatch + k;
            const double theta = std::remainder(double(step) * step_deg * std::numbers::pi / 180, 2 * std::numbers::pi);
            s.tip_x.push_back(8 + double(step) * dx_per_step_mm);
            s.tip_y.push_back(y);
            s.tip_z.push_back(z);
            s.feed_x.push_back(feed_per_tooth_mm);
            s.feed_y.push_back(0);
            s.feed_z.push_back(0);
            s.theta_rad.push_back(theta);
            s.cos_a.push_back(std::cos(std::numbers::pi / 2 - theta));
            s.sin_a.push_back(std::sin(std::numbers::pi / 2 - theta));
        }
        // The batch's path, removed as one segment over the cells it can reach.
        const double x0 = s.tip_x.front(), x1 = s.tip_x.back(), reach_mm = radius_mm + g.cell_mm;
        kernels::SweepCall call;
        call.segments = 1;
        call.i0 = std::max(0, int(std::floor((x0 - reach_mm - g.x0_mm) / g.cell_mm)));
        call.j0 = std::max(0, int(std::floor((y - reach_mm - g.y0_mm) / g.cell_mm)));
        call.width = std::min(g.nx, int(std::ceil((x1 + reach_mm - g.x0_mm) / g.cell_mm))) - call.i0;
        call.height = std::min(g.ny, int(std::ceil((y + reach_mm - g.y0_mm) / g.cell_mm))) - call.j0;
        c.segs.push_back({{x0, y, z, x1, y, z}});
        c.calls.push_back({call});
        c.batches.push_back(std::move(s));
    }
    return c;
}

struct Outputs {
    std::vector<std::vector<kernels::StepResult>> engaged;
    std::vector<std::vector<kernels::SweepCellResult>> swept;
    bool older_written_at_its_fence = true;   // overlapped runs: checked before the full wait
};

bool all_written(const std::vector<kernels::StepResult>& r) {
    for (const auto& s : r)
        if (std::isnan(s.fx_N) || std::isnan(s.engaged)) return false;
    return true;
}

bool all_written(const std::vector<kernels::SweepCellResult>& r) {
    for (const auto& s : r)
        if (std::isnan(s.removed_mm) || std::isnan(s.top_mm)) return false;
    return true;
}

// Engage then sweep each batch. Overlapped: batch b + 1's engagement is queued before waiting for
// batch b's fence, as the driver does; otherwise every call is followed by a full wait.
Outputs run(force_model::Device device, bool overlapped) {
    const auto spec = base_spec();
    const auto m = legs_motion({-6, 10, 7}, {{{46, 10, 7}, 3000, "N10"}});
    const force_model::ToolPlan plan = force_model::plan_tools(m, spec);
    force_model::PredictOptions opt;
    opt.device = device;
    const force_model::EngineSettings settings;
    force_model::EngineSetup setup(spec, plan, opt, settings);
    force_model::Backend& backend = *setup.backend;
    const force_model::ToolGeometry& tool = setup.tools.at(0);

    kernels::EngageParams p;
    force_model::set_kernel_law(setup.law, p);
    p.holder_face_z_mm = tool.stickout_mm;
    p.element_end = int(tool.edges.size());
    kernels::SweepParams sp;
    sp.lower_mm = tool.lower_mm;
    sp.radius_mm = tool.radius_mm;
    sp.cut_length_mm = tool.flute_length_mm;
    sp.wall_band_mm = setup.stock->grid.cell_mm;

    const Calls c = slot_calls(*setup.stock, tool.radius_mm);
    const float nan = std::numeric_limits<float>::quiet_NaN();
    Outputs out;
    for (int b = 0; b < kBatches; ++b) {
        out.engaged.emplace_back(kStepsPerBatch, kernels::StepResult{nan, nan, nan, nan, nan, nan, nan, nan, nan, nan, nan, nan});
        out.swept.emplace_back(c.calls[std::size_t(b)][0].cells(), kernels::SweepCellResult{nan, nan});
    }
    std::uint64_t older = 0;
    for (int b = 0; b < kBatches; ++b) {
        const std::size_t k = std::size_t(b);
        backend.engage(c.batches[k], p, out.engaged[k].data());
        if (!overlapped) backend.wait();
        if (overlapped && b > 0) {
            backend.wait_for(older);
            out.older_written_at_its_fence =
                out.older_written_at_its_fence && all_written(out.engaged[k - 1]) && all_written(out.swept[k - 1]);
        }
        backend.sweep(c.segs[k], c.calls[k], sp, out.swept[k].data());
        older = backend.fence();
        if (!overlapped) backend.wait();
    }
    backend.wait();
    return out;
}

bool same(const kernels::StepResult& a, const kernels::StepResult& b) {
    return a.fx_N == b.fx_N && a.fy_N == b.fy_N && a.fz_N == b.fz_N && a.torque_Nmm == b.torque_Nmm &&
           a.mx_Nmm == b.mx_Nmm && a.my_Nmm == b.my_Nmm && a.chip_mm == b.chip_mm && a.q_min_mm == b.q_min_mm &&
           a.q_max_mm == b.q_max_mm && a.z_min_mm == b.z_min_mm && a.z_max_mm == b.z_max_mm && a.engaged == b.engaged;
}

void check_same(const Outputs& serial, const Outputs& overlapped) {
    REQUIRE(serial.engaged.size() == overlapped.engaged.size());
    std::size_t cutting = 0, differing = 0, cells = 0, removing = 0;
    double removed_mm = 0;
    for (std::size_t b = 0; b < serial.engaged.size(); ++b) {
        CHECK(all_written(serial.engaged[b]));
        CHECK(all_written(overlapped.engaged[b]));
        for (std::size_t i = 0; i < serial.engaged[b].size(); ++i) {
            cutting += serial.engaged[b][i].engaged > 0 ? 1 : 0;
            differing += same(serial.engaged[b][i], overlapped.engaged[b][i]) ? 0 : 1;
        }
        for (std::size_t i = 0; i < serial.swept[b].size(); ++i) {
            const auto &s = serial.swept[b][i], &o = overlapped.swept[b][i];
            differing += s.removed_mm == o.removed_mm && s.top_mm == o.top_mm ? 0 : 1;
            removing += s.removed_mm > 0 ? 1 : 0;
            removed_mm += s.removed_mm;
            ++cells;
        }
    }
    CHECK(differing == 0);
    // The calls cut: a slot 3 mm deep engages the tool at most steps and removes material on
    // thousands of rays (2.5 mm x 8 mm per batch at 0.1 mm cells).
    CHECK(cutting > std::size_t(kBatches) * kStepsPerBatch / 2);
    CHECK(removing > 4000);
    CHECK(removed_mm > 3.0 * double(removing) * 0.9);
    INFO(cells << " rays swept");
}

}  // namespace

TEST_CASE("backend fences: the older batch is complete at its fence, and queuing the next one first changes no result",
          "[engine][opencl][pipeline]") {
    if (!opencl_available()) {
        WARN("no OpenCL device: nothing is queued (the scalar backend runs each call as it is made)");
        return;
    }
    const Outputs serial = run(force_model::Device::OpenCL, false);
    const Outputs overlapped = run(force_model::Device::OpenCL, true);
    CHECK(overlapped.older_written_at_its_fence);
    check_same(serial, overlapped);
}
