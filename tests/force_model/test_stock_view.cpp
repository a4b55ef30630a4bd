// The stock's height field for display: the top of the material per cell, against the closed form
// of a straight slot (flat end mill, D 8 mm): tip height inside |y - y_path| < 4 mm, the box top
// outside, no material where the slot goes through the bottom.
#include "force_model/engine_fixtures.hpp"

#include <catch2/catch.hpp>

#include <cmath>

using namespace cutload;
using namespace cutload::enginetest;

namespace {

force_model::Prediction slot_at(double z_tip_mm) {
    const auto spec = base_spec();   // box 40 x 20 x 10 mm, grid 0.1 mm
    const auto m = legs_motion({-10, 10, z_tip_mm}, {{{50, 10, z_tip_mm}, 3000, "N10"}});
    return run_on(m, spec, force_model::Device::Cpu);
}

// The slot's top at y (closed form); cells whose centre lies within a cell of the wall are skipped.
double slot_top(double y_mm, double z_tip_mm) { return std::abs(y_mm - 10.0) < 4.0 ? z_tip_mm : 10.0; }

}  // namespace

TEST_CASE("stock height field: every ray's top is the slot's closed form at full resolution") {
    const auto p = slot_at(7.0);
    const auto f = force_model::stock_height_field(*p.final_stock, 400 * 200);
    REQUIRE(f.rays_per_cell == 1);
    REQUIRE(f.nx == 400);
    REQUIRE(f.ny == 200);
    REQUIRE(f.cell_mm == Approx(0.1));
    REQUIRE(f.top_mm.size() == 400u * 200u);
    int checked = 0;
    for (int j = 0; j < f.ny; ++j) {
        const double y = f.y0_mm + (j + 0.5) * f.cell_mm;
        if (std::abs(std::abs(y - 10.0) - 4.0) < f.cell_mm) continue;
        for (int i = 0; i < f.nx; ++i) {
            INFO("cell " << i << "," << j << " y " << y);
            REQUIRE(f.top_mm[std::size_t(j) * 400 + std::size_t(i)] == Approx(slot_top(y, 7.0)).margin(1e-3));
            ++checked;
        }
    }
    REQUIRE(checked > 70000);
}

TEST_CASE("stock height field: a coarser field keeps the highest top of the rays it covers") {
    const auto p = slot_at(7.0);
    // 10 x 10 rays per cell: 40 x 20 cells of 1 mm; the slot's walls at y = 6 and 14 fall on
    // cell edges, so every cell is wholly inside or outside it.
    const auto f = force_model::stock_height_field(*p.final_stock, 800);
    REQUIRE(f.rays_per_cell == 10);
    REQUIRE(f.nx == 40);
    REQUIRE(f.ny == 20);
    for (int j = 0; j < f.ny; ++j)
        for (int i = 0; i < f.nx; ++i) {
            INFO("cell " << i << "," << j);
            REQUIRE(f.top_mm[std::size_t(j * 40 + i)] == Approx(j >= 6 && j < 14 ? 7.0 : 10.0).margin(1e-3));
        }
    // 9 rays per cell would need 45 x 23 = 1035 cells: over 1000, so 10 it is.
    REQUIRE(force_model::stock_height_field(*p.final_stock, 1000).rays_per_cell == 10);
    REQUIRE(force_model::stock_height_field(*p.final_stock, 1035).rays_per_cell == 9);
    REQUIRE_THROWS_AS(force_model::stock_height_field(*p.final_stock, 0), std::invalid_argument);
}

TEST_CASE("stock height field: a slot through the bottom leaves cells without material") {
    const auto p = slot_at(-1.0);
    const auto f = force_model::stock_height_field(*p.final_stock, 400 * 200);
    const auto at = [&](double y) { return f.top_mm[std::size_t(std::floor((y - f.y0_mm) / f.cell_mm)) * 400 + 200]; };
    CHECK(std::isnan(at(10.0)));
    CHECK(std::isnan(at(12.5)));
    CHECK(at(2.0) == Approx(10.0));
    CHECK(at(17.0) == Approx(10.0));
}
