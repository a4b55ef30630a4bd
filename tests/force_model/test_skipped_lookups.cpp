// Lookups skipped by the per-ray tops (docs/force_model.md, "Lookups skipped"). The OpenCL
// engagement leaves out an edge point over a ray whose top, or for a ray with a wall the highest top
// around it, is not above the element; remove.cl's refresh_tops keeps those tops after every
// removal. Checked here:
// - the tops the device holds equal refresh_tops_twin over the whole stock, after removals that
//   leave walls (fresh stock), as set up from a stock cut before (a base stock), and once engaging
//   resumes after removals made without (a window's lead-in);
// - the rows with lookups skipped equal, bit for bit, those with every edge point looked up
//   (EngineSettings::skip_lookups_below_tops), over a two-layer zig-zag pocket with round turns,
//   from a fresh stock and from that run's final stock.
// OpenCL only: the scalar twins look up every point.
#include "engine/setup.hpp"
#include "force_model/engine.hpp"
#include "force_model/stock.hpp"
#include "engine_fixtures.hpp"
#include "motion_fixtures.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <string>
#include <vector>

using namespace cutload;
using namespace cutload::enginetest;
using testref::line_to;

namespace {

// The removal of the setup's first cutter, as the engine asks for it.
kernels::SweepParams sweep_params(const force_model::EngineSetup& setup) {
    const force_model::ToolGeometry& tool = setup.tools.at(0);
    kernels::SweepParams sp;
    sp.lower_mm = tool.lower_mm;
    sp.radius_mm = tool.radius_mm;
    sp.cut_length_mm = tool.flute_length_mm;
    sp.wall_band_mm = setup.stock->grid.cell_mm;
    return sp;
}

// Three passes 1.5 mm apart along x over the fixture's block, 3 mm deep, each removed as one
// straight segment: every pass but the first cuts against the wall the one before left. Either a
// sweep per pass, each waited for, or all three calls in one sweep (overlapping rectangles, as a
// flush queues them) with a call of no width among them.
void cut_three_passes(force_model::Backend& backend, const force_model::Stock& stock, const kernels::SweepParams& sp,
                      bool one_sweep = false) {
    const auto& g = stock.grid;
    const double z = 7, reach_mm = sp.radius_mm + g.cell_mm;
    std::vector<kernels::SweepSegment> segs;
    std::vector<kernels::SweepCall> calls;
    for (int pass = 0; pass < 3; ++pass) {
        const double y = 8 + 1.5 * pass, x0 = 4, x1 = 30;
        kernels::SweepCall call;
        call.first_segment = segs.size();
        call.segments = 1;
        call.i0 = std::max(0, int(std::floor((x0 - reach_mm - g.x0_mm) / g.cell_mm)));
        call.j0 = std::max(0, int(std::floor((y - reach_mm - g.y0_mm) / g.cell_mm)));
        call.width = std::min(g.nx, int(std::ceil((x1 + reach_mm - g.x0_mm) / g.cell_mm))) - call.i0;
        call.height = std::min(g.ny, int(std::ceil((y + reach_mm - g.y0_mm) / g.cell_mm))) - call.j0;
        segs.push_back({x0, y, z, x1, y, z});
        calls.push_back(call);
        if (pass == 1) {
            kernels::SweepCall empty = call;
            empty.width = 0;
            calls.push_back(empty);
        }
    }
    if (one_sweep) {
        std::size_t cells = 0;
        for (const auto& c : calls) cells += c.cells();
        std::vector<kernels::SweepCellResult> out(cells);
        backend.sweep(segs, calls, sp, out.data());
        backend.wait();
        return;
    }
    for (const kernels::SweepCall& c : calls) {
        if (c.cells() == 0) continue;
        kernels::SweepCall alone = c;
        alone.first_segment = 0;
        std::vector<kernels::SweepCellResult> out(c.cells());
        backend.sweep({segs[c.first_segment]}, {alone}, sp, out.data());
        backend.wait();
    }
}

struct TopsCheck {
    std::size_t rays = 0, differing = 0, marked = 0, raised_by_neighbour = 0, cut = 0;
};

// The device's tops against the twin's over the whole stock (the twin from all-zero, a fresh
// stock's tops, so it writes every value that is not a ray never cut).
TopsCheck check_tops(force_model::Backend& backend, force_model::Stock& stock) {
    std::vector<std::uint32_t> device;
    REQUIRE(backend.read_lookup_tops(device));
    backend.download(stock);
    std::vector<std::uint32_t> twin(stock.rays(), 0);
    kernels::refresh_tops_twin(stock.view(), 0, 0, stock.grid.nx, stock.grid.ny, twin.data());
    REQUIRE(device.size() == twin.size());
    TopsCheck c;
    const std::uint32_t base = std::bit_cast<std::uint32_t>(stock.codec.base_top());
    for (std::size_t r = 0; r < twin.size(); ++r) {
        ++c.rays;
        c.differing += device[r] != twin[r] ? 1 : 0;
        const kernels::Ray ray = stock.ray(r);
        const float own = kernels::ray_top(ray);
        c.cut += own < stock.codec.base_top() ? 1 : 0;
        if (kernels::has_wall_mark(ray.data())) {
            ++c.marked;
            c.raised_by_neighbour += std::bit_cast<float>(twin[r] ^ base) > own ? 1 : 0;
        }
    }
    return c;
}

// Two layers of zig-zag pocketing over the fixture's 40 x 20 block (ap 3 mm, stepover 2.5 mm with
// half-circle turns), so most edge points ahead of the tool lie over stock already cut down, and
// many over rays with walls; an air move between the layers.
testref::Path pocket_path() {
    testref::Path p;
    p.feed_mm_min = 3000;
    p.spindle_rpm = 10000;
    p.start_mm = {-6, 3, 7};
    auto layer = [&](double z, const std::string& name) { testref::add_zigzag_layer(p, z, name, 3, 2.5, 4, 34); };
    layer(7, "L1");
    p.segments.push_back(line_to({-6, 16, 20}, "lift"));
    p.segments.push_back(line_to({-6, 3, 20}, "back"));
    p.segments.push_back(line_to({-6, 3, 4}, "down"));
    layer(4, "L2");
    return p;
}

force_model::Prediction predict_pocket(const motion_io::MotionModel& m, bool skip, const force_model::Stock* base = nullptr) {
    force_model::PredictOptions o;
    o.device = force_model::Device::OpenCL;
    o.base_stock = base;
    force_model::EngineSettings settings;
    settings.skip_lookups_below_tops = skip;
    // A block top between element ends (the elements are 0.1 mm tall from the tip up): the top
    // elements are partly engaged, and a ray's top lies inside them.
    return force_model::predict_with(m, base_spec(40, 20, 9.93), o, settings);
}

void require_same_rows(const force_model::Prediction& skipped, const force_model::Prediction& all) {
    REQUIRE(skipped.samples.size() == all.samples.size());
    std::size_t differing = 0, cutting = 0;
    for (std::size_t i = 0; i < all.samples.size(); ++i) {
        differing += same_row(skipped.samples[i], all.samples[i]) ? 0 : 1;
        cutting += all.samples[i].chip_mm > 0 ? 1 : 0;
    }
    CHECK(differing == 0);
    // The pocket cuts: most of its rows engage the tool.
    CHECK(cutting > all.samples.size() / 4);
    REQUIRE(skipped.blocks.size() == all.blocks.size());
    for (std::size_t b = 0; b < all.blocks.size(); ++b) CHECK(skipped.blocks[b].peak_force_N == all.blocks[b].peak_force_N);
}

}  // namespace

TEST_CASE("skipped lookups: the device's per-ray tops are refresh_tops_twin's, after removals and from a cut stock",
          "[engine][opencl][skipped_lookups]") {
    if (!opencl_available()) {
        WARN("no OpenCL device: the scalar twins keep no tops");
        return;
    }
    const auto spec = base_spec();
    const auto m = legs_motion({-6, 10, 7}, {{{46, 10, 7}, 3000, "N10"}});
    const force_model::ToolPlan plan = force_model::plan_tools(m, spec);
    force_model::PredictOptions opt;
    opt.device = force_model::Device::OpenCL;
    const force_model::EngineSettings settings;
    force_model::StockPtr cut;
    {
        force_model::EngineSetup setup(spec, plan, opt, settings);
        const kernels::SweepParams sp = sweep_params(setup);
        // A fresh stock: all tops are a ray never cut's.
        const TopsCheck fresh = check_tops(*setup.backend, *setup.stock);
        CHECK(fresh.differing == 0);
        CHECK(fresh.cut == 0);
        cut_three_passes(*setup.backend, *setup.stock, sp);
        const TopsCheck after = check_tops(*setup.backend, *setup.stock);
        INFO(after.cut << " rays cut, " << after.marked << " with a wall, " << after.raised_by_neighbour
                       << " of those raised by a neighbour");
        CHECK(after.differing == 0);
        // The passes cut thousands of rays, leave walls, and some walled rays take a neighbour's top.
        CHECK(after.cut > 5000);
        CHECK(after.marked > 200);
        CHECK(after.raised_by_neighbour > 50);
        cut = force_model::copy_stock(*setup.stock);
    }
    // The same stock as a base stock: the tops are set up from it.
    opt.base_stock = cut.get();
    {
        force_model::EngineSetup again(spec, plan, opt, settings);
        const TopsCheck from_base = check_tops(*again.backend, *again.stock);
        CHECK(from_base.differing == 0);
        CHECK(from_base.cut > 5000);
    }
    // The three passes as one flush's calls.
    opt.base_stock = nullptr;
    {
        force_model::EngineSetup flush(spec, plan, opt, settings);
        cut_three_passes(*flush.backend, *flush.stock, sweep_params(flush), true);
        const TopsCheck one_sweep = check_tops(*flush.backend, *flush.stock);
        CHECK(one_sweep.differing == 0);
        CHECK(one_sweep.cut > 5000);
        CHECK(one_sweep.raised_by_neighbour > 50);
    }
    // Removals with no engagement to follow (a window's lead-in) leave the tops as they were, and
    // those they may have changed are rebuilt when engaging resumes.
    force_model::EngineSetup lead_in(spec, plan, opt, settings);
    lead_in.backend->set_engaging(false);
    cut_three_passes(*lead_in.backend, *lead_in.stock, sweep_params(lead_in));
    std::vector<std::uint32_t> stale;
    REQUIRE(lead_in.backend->read_lookup_tops(stale));
    CHECK(std::all_of(stale.begin(), stale.end(), [](std::uint32_t t) { return t == 0; }));
    lead_in.backend->set_engaging(true);
    const TopsCheck rebuilt = check_tops(*lead_in.backend, *lead_in.stock);
    CHECK(rebuilt.differing == 0);
    CHECK(rebuilt.cut > 5000);
    CHECK(rebuilt.raised_by_neighbour > 50);
}

TEST_CASE("skipped lookups: a two-layer pocket gives the same rows as with every edge point looked up",
          "[engine][opencl][skipped_lookups]") {
    if (!opencl_available()) {
        WARN("no OpenCL device: the scalar twins look up every point");
        return;
    }
    const motion_io::MotionModel m = testref::uniform_motion(pocket_path());
    const force_model::Prediction skipped = predict_pocket(m, true);
    const force_model::Prediction all = predict_pocket(m, false);
    require_same_rows(skipped, all);
    // Again from that pocket's stock, half a stepover aside and 6 mm deeper: the tops are set up
    // from a stock with walls, and the passes cut below the first run's floor and into its walls.
    REQUIRE(all.final_stock);
    // (uniform_motion's offset is the work offset: the path moves by minus it.)
    const motion_io::MotionModel aside = testref::uniform_motion(pocket_path(), 0.001, {0, -1.25, 6});
    require_same_rows(predict_pocket(aside, true, all.final_stock.get()),
                      predict_pocket(aside, false, all.final_stock.get()));
}

TEST_CASE("skipped lookups: wall normals out of range in a start stock still give the rows of every point looked up",
          "[engine][opencl][skipped_lookups]") {
    if (!opencl_available()) {
        WARN("no OpenCL device: the scalar twins look up every point");
        return;
    }
    // A stock file's walls are not checked for unit normals (a damaged or hostile file with a good
    // checksum). The ray read across a wall is clamped to the 3 x 3 around the ray, which the tops
    // of walled rays cover, so skipping still leaves out only lookups that find nothing.
    const motion_io::MotionModel m = testref::uniform_motion(pocket_path());
    const force_model::Prediction first = predict_pocket(m, false);
    REQUIRE(first.final_stock);
    force_model::StockPtr odd = force_model::copy_stock(*first.final_stock);
    const kernels::DexelView v = odd->view();
    std::size_t scaled = 0;
    for (std::size_t r = 0; r < odd->rays(); ++r)
        for (int slot = 0; slot < kernels::kWallSlots; ++slot) {
            kernels::Wall w = v.wall(r, slot);
            if (!w.exists()) continue;
            w.nx *= 3.5f;
            w.ny *= 3.5f;
            v.store_wall(r, w, slot);
            ++scaled;
        }
    REQUIRE(scaled > 1000);
    const motion_io::MotionModel aside = testref::uniform_motion(pocket_path(), 0.001, {0, -1.25, 6});
    require_same_rows(predict_pocket(aside, true, odd.get()), predict_pocket(aside, false, odd.get()));
}
