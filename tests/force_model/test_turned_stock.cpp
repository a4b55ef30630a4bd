// A stock box held for a tilted tool (force_model::make_turned_stock): rays along the tool's axis
// on a grid in its frame. Checked against the box's closed forms: its volume, the chord each ray
// holds, the frame kept through save and load, and its top seen from above in stock axes.
#include "force_model/force_model.hpp"
#include "force_model/stock.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <numbers>

using namespace cutload;

namespace {

// The rotation that takes stock coordinates into the frame of a tool whose axis leans by `lean`
// about the stock's y and then turns by `turn` about z (any rotation will do: the test checks
// geometry, not a machine).
force_model::Rotation3 frame(double lean_deg, double turn_deg) {
    const double l = lean_deg * std::numbers::pi / 180, t = turn_deg * std::numbers::pi / 180;
    // tool_to_stock = Rz(t) Ry(l); grid_from_stock is its transpose.
    const double cl = std::cos(l), sl = std::sin(l), ct = std::cos(t), st = std::sin(t);
    const double R[9] = {ct * cl, -st, ct * sl, st * cl, ct, st * sl, -sl, 0, cl};
    force_model::Rotation3 g;
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) g.m[std::size_t(3 * r + c)] = R[3 * c + r];
    return g;
}

force_model::StockBox box() {
    force_model::StockBox b;
    b.min_mm[0] = 10, b.min_mm[1] = -20, b.min_mm[2] = -30;
    b.max_mm[0] = 50, b.max_mm[1] = 5, b.max_mm[2] = -10;
    return b;
}

}  // namespace

TEST_CASE("turned stock: the box's volume and chords at any orientation, the identity as make_stock", "[stock][fixed_tilt]") {
    const force_model::StockBox b = box();
    const double volume = 40.0 * 25 * 20;
    SECTION("identity: the rays of make_stock") {
        const auto turned = force_model::make_turned_stock(b, force_model::Rotation3{}, 0.5);
        const auto plain = force_model::make_stock(b, 0.5);
        REQUIRE(turned->rays() == plain->rays());
        for (std::size_t r = 0; r < plain->rays(); ++r) REQUIRE(turned->ray(r) == plain->ray(r));
        CHECK(force_model::stock_grid_frame(*turned).is_identity());
    }
    const auto [lean, turn] = GENERATE(std::pair{30.0, 0.0}, std::pair{15.0, 40.0}, std::pair{60.0, -110.0},
                                       std::pair{90.0, 0.0});
    INFO("lean " << lean << " deg, turn " << turn << " deg");
    const force_model::Rotation3 g = frame(lean, turn);
    const auto s = force_model::make_turned_stock(b, g, 0.2);
    // The rays sample the turned box at their centres: the volume to within the cells along its
    // rim (perimeter x cell x height, a few per cent at this grid; measured well under 0.5 %).
    CHECK(force_model::stock_volume_mm3(*s) == Approx(volume).epsilon(0.005));
    CHECK(force_model::stock_grid_frame(*s).m == g.m);
    const force_model::StockBox source = force_model::stock_box(*s);
    for (int k = 0; k < 3; ++k) CHECK(source.min_mm[k] == b.min_mm[k]);
    // A ray through the box's centre holds one interval whose ends lie on the box's faces.
    const double c[3] = {30, -7.5, -20};
    const double gx = g.m[0] * c[0] + g.m[1] * c[1] + g.m[2] * c[2], gy = g.m[3] * c[0] + g.m[4] * c[1] + g.m[5] * c[2];
    const int i = int((gx - s->grid.x0_mm) / s->grid.cell_mm), j = int((gy - s->grid.y0_mm) / s->grid.cell_mm);
    const kernels::Ray ray = s->ray(i, j);
    REQUIRE(ray[1] == kernels::kEmptyLo);
    REQUIRE(ray[4] > ray[0]);
    const double x = s->grid.x0_mm + (i + 0.5) * s->grid.cell_mm, y = s->grid.y0_mm + (j + 0.5) * s->grid.cell_mm;
    for (const float t : {ray[0], ray[4]}) {
        // The end, back in stock coordinates, lies on a face and inside the others.
        const double p[3] = {g.m[0] * x + g.m[3] * y + g.m[6] * t, g.m[1] * x + g.m[4] * y + g.m[7] * t,
                             g.m[2] * x + g.m[5] * y + g.m[8] * t};
        double on_face = 1e9;
        for (int k = 0; k < 3; ++k) {
            CHECK(p[k] >= b.min_mm[k] - 1e-4);
            CHECK(p[k] <= b.max_mm[k] + 1e-4);
            on_face = std::min({on_face, std::abs(p[k] - b.min_mm[k]), std::abs(p[k] - b.max_mm[k])});
        }
        CHECK(on_face < 1e-4);
    }
}

TEST_CASE("turned stock: save and load keep the frame, the view from above is in stock axes", "[stock][fixed_tilt]") {
    const force_model::StockBox b = box();
    const force_model::Rotation3 g = frame(25, 30);
    const auto s = force_model::make_turned_stock(b, g, 0.25);
    const auto back = force_model::load_stock_bytes(force_model::save_stock_bytes(*s), "turned stock");
    CHECK(force_model::stock_grid_frame(*back).m == g.m);
    const force_model::StockBox source = force_model::stock_box(*back);
    for (int k = 0; k < 3; ++k) {
        CHECK(source.min_mm[k] == b.min_mm[k]);
        CHECK(source.max_mm[k] == b.max_mm[k]);
    }
    REQUIRE(back->rays() == s->rays());
    for (std::size_t r = 0; r < s->rays(); ++r) REQUIRE(back->ray(r) == s->ray(r));

    // A frame that is not a rotation (a scaled or mirrored grid) is refused even under a good
    // checksum: the format (docs/formats.md) puts the frame at byte 96 and FNV-1a 64 of every
    // byte before it at the end.
    for (const double bad : {2.0, -1.0, std::nan("")}) {
        std::string bytes = force_model::save_stock_bytes(*s);
        std::memcpy(bytes.data() + 96, &bad, sizeof bad);
        std::uint64_t h = 1469598103934665603ull;
        for (std::size_t k = 0; k + 8 < bytes.size(); ++k) h = (h ^ static_cast<unsigned char>(bytes[k])) * 1099511628211ull;
        std::memcpy(bytes.data() + bytes.size() - 8, &h, sizeof h);
        INFO("frame[0] = " << bad);
        CHECK_THROWS_WITH(force_model::load_stock_bytes(bytes, "run 7's stock"),
                          Catch::StartsWith("run 7's stock: ") && Catch::Contains("frame is not a rotation"));
    }
}

TEST_CASE("turned stock: seen from above in stock axes, the box's top face at any lean, a horizontal tool's included",
          "[stock][fixed_tilt]") {
    const force_model::StockBox b = box();
    const auto [lean, turn] = GENERATE(std::pair{25.0, 30.0}, std::pair{60.0, -20.0}, std::pair{90.0, 0.0},
                                       std::pair{90.0, 90.0}, std::pair{120.0, 45.0});
    INFO("lean " << lean << " deg, turn " << turn << " deg");
    const double pitch_mm = 0.25;
    const auto s = force_model::make_turned_stock(b, frame(lean, turn), pitch_mm);
    // The box's top face at z = -10 over its own x-y extent; no cell higher than the top (the field
    // never shows material that is not there), none lower than a ray pitch under it inside.
    const force_model::StockHeightField f = force_model::stock_height_field(*s, 200 * 200);
    CHECK(f.x0_mm == b.min_mm[0]);
    CHECK(f.y0_mm == b.min_mm[1]);
    std::size_t inner = 0, near_top = 0;
    for (int j = 0; j < f.ny; ++j)
        for (int i = 0; i < f.nx; ++i) {
            const float top = f.top_mm[std::size_t(j) * std::size_t(f.nx) + std::size_t(i)];
            if (!std::isnan(top)) CHECK(top <= b.max_mm[2] + 1e-4);
            const double x = f.x0_mm + (i + 0.5) * f.cell_mm, y = f.y0_mm + (j + 0.5) * f.cell_mm;
            if (x < b.min_mm[0] + 1 || x > b.max_mm[0] - 1 || y < b.min_mm[1] + 1 || y > b.max_mm[1] - 1) continue;
            ++inner;
            if (!std::isnan(top) && top >= b.max_mm[2] - pitch_mm - 1e-3) ++near_top;
        }
    REQUIRE(inner > 1000);
    CHECK(near_top == inner);
}
