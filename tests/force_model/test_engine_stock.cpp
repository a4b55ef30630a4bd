// Stock model: swept-volume removal volumes, multi-interval rays, save/load.
#include "force_model/engine.hpp"
#include "force_model/engine_fixtures.hpp"

#include <catch2/catch.hpp>

#include <cstdio>
#include <filesystem>
#include <fstream>

using namespace cutload;
using namespace cutload::enginetest;
using force_model::Device;

namespace {

force_model::Prediction run(const motion_io::MotionModel& m, const force_model::RunSpec& s, Device d = Device::Cpu,
                            const force_model::Stock* base = nullptr) {
    force_model::PredictOptions o;
    o.device = d;
    o.base_stock = base;
    return force_model::predict(m, s, o);
}

std::string temp_path(const std::string& name) {
    return (std::filesystem::temp_directory_path() / ("cutload_engine_" + name)).string();
}

}  // namespace

TEST_CASE("straight slot removes width x depth x length") {
    const auto spec = base_spec();
    // Across the whole 40 mm box at 3 mm depth, 8 mm wide.
    const auto m = legs_motion({-10, 10, 7}, {{{50, 10, 7}, 3000, "N10"}});
    const double before = force_model::stock_volume_mm3(*force_model::make_stock(spec.stock, 0.1));
    const auto p = run(m, spec);
    const double removed = before - force_model::stock_volume_mm3(*p.final_stock);
    CHECK(removed == Approx(8 * 3 * 40).epsilon(0.01));
    double rows_removed = 0;
    for (const auto& s : p.samples) rows_removed += s.removed_mm3;
    CHECK(rows_removed == Approx(removed).epsilon(1e-3));
    REQUIRE(p.blocks.size() == 1);
    CHECK(p.blocks[0].removed_mm3 == Approx(removed).epsilon(1e-3));
}

TEST_CASE("through-cut empties the rays and leaves the walls") {
    const auto spec = base_spec();
    const auto m = legs_motion({-10, 10, -1}, {{{50, 10, -1}, 3000, "N10"}});
    const auto p = run(m, spec);
    const auto& st = *p.final_stock;
    CHECK(kernels::ray_length(st.ray(200, 100)) == 0);     // x 20, y 10: slot centre
    CHECK(kernels::ray_length(st.ray(200, 20)) == Approx(10)); // y 2: outside the slot
    const double removed = 40 * 20 * 10 - force_model::stock_volume_mm3(st);
    CHECK(removed == Approx(8 * 10 * 40).epsilon(0.01));
}

TEST_CASE("a cut below material leaves two intervals per ray") {
    auto spec = base_spec();
    spec.tool.flute_length_mm = 4;   // cuts [3, 7]; the shank rubs the material above
    const auto m = legs_motion({-10, 10, 3}, {{{50, 10, 3}, 3000, "N10"}});
    const auto p = run(m, spec);
    const kernels::Ray ray = p.final_stock->ray(200, 100);
    CHECK(ray[0] == Approx(0));
    CHECK(ray[kernels::kDexelIntervals] == Approx(3));
    CHECK(ray[1] == Approx(7));
    CHECK(ray[kernels::kDexelIntervals + 1] == Approx(10));
    CHECK(ray[2] == kernels::kEmptyLo);
    REQUIRE(p.blocks.size() == 1);
    bool holder = false;
    for (const auto& f : p.blocks[0].flags) holder |= f.flag == "holder_contact";
    CHECK(holder);
}

TEST_CASE("pocket: plunge then a square leaves the floor at depth") {
    const auto spec = base_spec();
    const auto m = legs_motion({20, 10, 15}, {{{20, 10, 8}, 300, "plunge"},
                                              {{24, 10, 8}, 1000, "a"},
                                              {{24, 12, 8}, 1000, "b"},
                                              {{16, 12, 8}, 1000, "c"},
                                              {{16, 8, 8}, 1000, "d"},
                                              {{24, 8, 8}, 1000, "e"},
                                              {{20, 10, 15}, 3000, "retract"}});
    const auto p = run(m, spec);
    const auto& st = *p.final_stock;
    CHECK(kernels::ray_top(st.ray(200, 100)) == Approx(8));   // pocket centre at depth 2
    CHECK(kernels::ray_top(st.ray(20, 100)) == Approx(10));   // x 2: untouched
    // Pocket: 16 x 12 rectangle of the tool centres' hull, with rounded corners (r 4).
    const double area = (8 + 8) * (4 + 8) - (4 - std::acos(-1.0)) * 16;
    CHECK((40 * 20 * 10 - force_model::stock_volume_mm3(st)) == Approx(area * 2).epsilon(0.02));
    CHECK(p.blocks.size() == 7);
}

TEST_CASE("stock save and load round trip, corrupt files are rejected") {
    const auto spec = base_spec();
    const auto m = legs_motion({-10, 10, 7}, {{{50, 10, 7}, 3000, "N10"}});
    const auto p = run(m, spec);
    const std::string path = temp_path("stock.bin");
    force_model::save_stock(*p.final_stock, path);
    const auto back = force_model::load_stock(path);
    REQUIRE(back->rays() == p.final_stock->rays());
    std::size_t differing = 0;
    for (std::size_t r = 0; r < back->rays(); ++r) differing += back->ray(r) == p.final_stock->ray(r) ? 0 : 1;
    CHECK(differing == 0);
    // The sub-cell walls travel with the rays (a finishing run from a saved roughing stock).
    std::size_t walls = 0, differing_walls = 0;
    for (std::size_t r = 0; r < back->rays(); ++r) {
        const kernels::Wall a = back->view().wall(r), b = p.final_stock->view().wall(r);
        walls += b.exists() ? 1 : 0;
        differing_walls += a.clearance_mm == b.clearance_mm && a.z_from_mm == b.z_from_mm && a.nx == b.nx &&
                                   a.ny == b.ny
                               ? 0
                               : 1;
    }
    CHECK(walls >= 2 * 400);   // both walls of the slot across the 40 mm box: a ray per cell or more
    CHECK(differing_walls == 0);
    CHECK(back->grid.nx == p.final_stock->grid.nx);
    CHECK(force_model::stock_volume_mm3(*back) == Approx(force_model::stock_volume_mm3(*p.final_stock)));

    const auto bytes = std::filesystem::file_size(path);
    {
        std::fstream f(path, std::ios::in | std::ios::out | std::ios::binary);
        f.seekp(std::streamoff(bytes / 2));
        f.put('\x7f');
    }
    CHECK_THROWS_WITH(force_model::load_stock(path), Catch::Contains("checksum"));
    std::filesystem::resize_file(path, bytes / 3);
    CHECK_THROWS_WITH(force_model::load_stock(path), Catch::Contains("truncated"));
    {
        std::ofstream f(path, std::ios::binary | std::ios::trunc);
        f << "not a stock file at all, just text padding padding padding padding padding";
    }
    CHECK_THROWS_WITH(force_model::load_stock(path), Catch::Contains("magic"));
    CHECK_THROWS_WITH(force_model::load_stock(temp_path("missing.bin")), Catch::Contains("cannot open"));
    std::filesystem::remove(path);
}

TEST_CASE("a run can start from another run's stock") {
    const auto spec = base_spec();
    const auto rough = legs_motion({-10, 10, 7}, {{{50, 10, 7}, 3000, "rough"}});
    const auto p1 = run(rough, spec);
    // The same pass again cuts air: no force, nothing removed.
    const auto p2 = run(rough, spec, Device::Cpu, p1.final_stock.get());
    double peak = 0, removed = 0;
    for (const auto& s : p2.samples) {
        peak = std::max(peak, double(std::hypot(s.fx_N, s.fy_N, s.fz_N)));
        removed += s.removed_mm3;
    }
    CHECK(peak == 0);
    CHECK(removed == 0);
    const auto fresh = run(rough, spec);
    CHECK(fresh.blocks[0].peak_force_N > 100);
}

TEST_CASE("a fresh stock is the full box without a fill, copies keep every ray") {
    const auto spec = base_spec();
    const auto fresh = force_model::make_stock(spec.stock, 0.1);
    // Untouched rays are stored as zero bytes and read back as the box's full column.
    CHECK(fresh->untouched(0));
    CHECK(fresh->untouched(fresh->rays() - 1));
    const kernels::Ray column = fresh->ray(123, 45);
    CHECK(column[0] == 0.0f);
    CHECK(column[kernels::kDexelIntervals] == 10.0f);
    CHECK(column[1] == kernels::kEmptyLo);
    CHECK(force_model::stock_volume_mm3(*fresh) == Approx(40 * 20 * 10));

    const auto p = run(legs_motion({-10, 10, 7}, {{{50, 10, 7}, 3000, "N10"}}), spec);
    const auto& cut = *p.final_stock;
    CHECK_FALSE(cut.untouched(std::size_t(100) * cut.grid.nx + 200));   // slot centre
    CHECK(cut.untouched(std::size_t(20) * cut.grid.nx + 200));          // y 2: outside the slot
    const auto copy = force_model::copy_stock(cut);
    std::size_t differing = 0;
    for (std::size_t r = 0; r < cut.rays(); ++r) differing += copy->ray(r) == cut.ray(r) ? 0 : 1;
    CHECK(differing == 0);
    CHECK(force_model::stock_volume_mm3(*copy) == Approx(force_model::stock_volume_mm3(cut)));
}
