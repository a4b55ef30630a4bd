// The multi-direction (tri-dexel) stock and its removal by a tool at any orientation
// (kernels/tri_dexel.hpp, docs/five_axis.md section 3): the tool solid against the closed forms of
// a cylinder and a ball, and swept removal against the cross-sections the cuts leave (a horizontal
// slot, a tilted ball groove, an undercut groove), in every family.
#include "force_model/cutters/profile.hpp"
#include "force_model/cutters/shapes.hpp"
#include "kernels/tri_dexel.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <numbers>
#include <random>
#include <stdexcept>

using namespace cutload;
using kernels::ToolChord;
using Vec = std::array<double, 3>;

namespace {

constexpr double kCellMm = 0.1;
constexpr double kSagittaMm = kCellMm / 64;

kernels::ConvexToolSolid solid_of(const force_model::CutterProfile& profile, double sagitta_mm = kSagittaMm) {
    std::vector<std::array<double, 2>> rz;
    for (const auto& p : force_model::profile_polyline(profile, sagitta_mm)) rz.push_back({p.r_mm, p.z_mm});
    return kernels::convex_tool_solid(rz);
}

Vec cross(const Vec& a, const Vec& b) {
    return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
double dot(const Vec& a, const Vec& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

// A chord with the tool's x and z axes given in stock coordinates (y = z cross x).
ToolChord chord(const Vec& from, const Vec& to, const Vec& x_axis, const Vec& z_axis) {
    const Vec y_axis = cross(z_axis, x_axis);
    ToolChord c;
    c.from_mm = from;
    c.to_mm = to;
    for (int r = 0; r < 3; ++r) c.rot[r] = {x_axis[r], y_axis[r], z_axis[r]};
    return c;
}

// Area of the circular segment of height h in a circle of radius R.
double segment_area(double R, double h) { return R * R * std::acos((R - h) / R) - (R - h) * std::sqrt(2 * R * h - h * h); }

// The part of the line p + t u (u unit) inside a ball end mill of radius R and flute length L in
// its own frame, from the closed form: points within R of the axis's half-line above the ball's
// centre (z >= R), cut by the slab 0 <= z <= L. Brute force over t, written from the definition.
bool line_in_ball_mill(double R, double L, const Vec& p, const Vec& u, double& t_in, double& t_out) {
    auto inside = [&](double t) {
        const Vec q{p[0] + t * u[0], p[1] + t * u[1], p[2] + t * u[2]};
        if (q[2] < 0 || q[2] > L) return false;
        const double above = std::max(q[2] - R, 0.0);   // nearest point of the half-line
        const double dz = q[2] - R - above;
        return q[0] * q[0] + q[1] * q[1] + dz * dz <= R * R;
    };
    bool any = false;
    const double step = 1e-4;
    for (double t = -40; t <= 40; t += step)
        if (inside(t)) {
            if (!any) t_in = t;
            t_out = t;
            any = true;
        }
    return any;
}

}  // namespace

TEST_CASE("tri-dexel: a line meets a flat and a ball end mill where the closed forms say", "[tri_dexel]") {
    const auto flat = solid_of(force_model::corner_radius_profile(8, 0, 20));
    double a = 0, b = 0;
    // Across the cylinder 1.5 mm off the axis: the chord is 2 sqrt(4^2 - 1.5^2).
    REQUIRE(kernels::line_in_solid(flat, {-10, 1.5, 5}, {1, 0, 0}, a, b));
    CHECK(a == Approx(10 - std::sqrt(16 - 2.25)).margin(1e-9));
    CHECK(b == Approx(10 + std::sqrt(16 - 2.25)).margin(1e-9));
    // Along the axis: from the flat bottom to the end of the flutes.
    REQUIRE(kernels::line_in_solid(flat, {1, 0, -5}, {0, 0, 1}, a, b));
    CHECK(a == Approx(5).margin(1e-9));
    CHECK(b == Approx(25).margin(1e-9));
    CHECK_FALSE(kernels::line_in_solid(flat, {-10, 4.01, 5}, {1, 0, 0}, a, b));
    CHECK_FALSE(kernels::line_in_solid(flat, {-10, 0, -0.01}, {1, 0, 0}, a, b));

    // A ball end mill, R 3, against lines in every direction: the polyline lies inside the ball by
    // at most the sagitta, so an end moves by at most sagitta / sin(the line's angle to the surface).
    const double R = 3, L = 12;
    const auto ball = solid_of(force_model::corner_radius_profile(2 * R, R, L));
    std::mt19937 rng(15);
    std::uniform_real_distribution<double> pos(-3, 3), height(-2, 14), dir(-1, 1);
    int compared = 0;
    for (int k = 0; k < 200; ++k) {
        Vec u{dir(rng), dir(rng), dir(rng)};
        const double n = std::sqrt(dot(u, u));
        if (n < 0.2) continue;
        for (double& c : u) c /= n;
        // Start 20 mm back along the line from a point near the tool, so t is positive.
        const Vec q{pos(rng), pos(rng), height(rng)};
        const Vec p{q[0] - 20 * u[0], q[1] - 20 * u[1], q[2] - 20 * u[2]};
        double ea = 0, eb = 0;
        const bool expected = line_in_ball_mill(R, L, p, u, ea, eb);
        const bool got = kernels::line_in_solid(ball, p, u, a, b);
        if (expected && eb - ea > 0.05) {
            REQUIRE(got);
            CHECK(a == Approx(ea).margin(0.02));
            CHECK(b == Approx(eb).margin(0.02));
            ++compared;
        } else if (!expected) {
            CHECK_FALSE(got);
        }
    }
    CHECK(compared > 40);
}

TEST_CASE("tri-dexel: a profile with a neck is refused, since its solid is not convex", "[tri_dexel]") {
    CHECK_THROWS_AS(kernels::convex_tool_solid({{0, 0}, {4, 0}, {4, 5}, {3, 10}, {4, 15}}), std::invalid_argument);
    CHECK_THROWS_AS(kernels::convex_tool_solid({{0, 0}, {4, 0}, {5, 0}}), std::invalid_argument);
    CHECK_NOTHROW(kernels::convex_tool_solid({{0, 0}, {4, 0}, {4, 5}, {3.5, 10}}));   // a taper narrowing up
    CHECK_THROWS_AS(kernels::make_tri_dexel_box({0, 0, 0}, {10, 0, 5}, 0.1), std::invalid_argument);
}

TEST_CASE("tri-dexel: a horizontal flat end mill slots a vertical face by D x depth per mm (S1)", "[tri_dexel]") {
    // Stock x 0..30, y 0..40, z 0..20. The tool lies along X with the spindle on the -X side, its
    // tip 2 mm into the face x = 0, centred at z = 10, and runs along Y past both ends: a slot
    // 8 mm wide (in z), 2 mm deep (in x), 40 mm long.
    auto stock = kernels::make_tri_dexel_box({0, 0, 0}, {30, 40, 20}, kCellMm);
    const double before = stock.volume_mm3(2);
    CHECK(before == Approx(30 * 40 * 20).epsilon(1e-9));
    const auto tool = solid_of(force_model::corner_radius_profile(8, 0, 20));
    const ToolChord c = chord({2, -10, 10}, {2, 50, 10}, {0, 0, 1}, {-1, 0, 0});
    const auto removed = kernels::sweep_tri_dexel(stock, tool, &c, 1);
    for (int f = 0; f < 3; ++f) {
        INFO("family " << "xyz"[f]);
        CHECK(removed[f] == Approx(8 * 2 * 40).epsilon(0.005));
        CHECK(before - stock.volume_mm3(f) == Approx(removed[f]).epsilon(1e-6));
    }
    // The X rays through the slot start at the slot's floor, exactly.
    const auto& fx = stock.family[0];   // rays along x, grid over (y, z)
    const float* in_slot = fx.ray(std::size_t(100) * fx.nu + 200);   // y 20.05, z 10.05
    CHECK(in_slot[0] == Approx(2).margin(1e-4));
    const float* above = fx.ray(std::size_t(150) * fx.nu + 200);   // z 15.05: untouched
    CHECK(above[0] == Approx(0).margin(1e-6));
    // Inside tests: a point just past the floor is material on the X family, one just before it air.
    CHECK(kernels::best_family({1, 0, 0}) == 0);
    CHECK(kernels::tri_dexel_contains(stock, 0, {2.01, 20, 10}));
    CHECK_FALSE(kernels::tri_dexel_contains(stock, 0, {1.99, 20, 10}));
    CHECK_FALSE(kernels::tri_dexel_contains(stock, 0, {-1, 20, 10}));   // outside the box
}

TEST_CASE("tri-dexel: a ball end mill leaning 30 deg cuts the circular segment of its ball, along and across its lean",
          "[tri_dexel]") {
    // Ball R 3 with its centre 2 mm above the top face (depth 1): only the ball reaches the stock
    // (the shank's lowest point stays R sin 30 = 1.5 mm below the centre, above the face), and a
    // ball's section does not depend on its lean. Per mm of path: the segment of height 1.
    const double R = 3, depth = 1;
    const double area = segment_area(R, depth);
    const double s = std::sin(std::numbers::pi / 6), c = std::cos(std::numbers::pi / 6);
    const Vec axis{0, -s, c};
    const auto tool = solid_of(force_model::corner_radius_profile(2 * R, R, 15));
    auto tip_for_centre = [&](Vec centre) {
        for (int k = 0; k < 3; ++k) centre[k] -= R * axis[k];
        return centre;
    };
    SECTION("across the lean (along X)") {
        auto stock = kernels::make_tri_dexel_box({0, 0, 0}, {40, 30, 20}, kCellMm);
        const ToolChord ch = chord(tip_for_centre({-5, 15, 22}), tip_for_centre({45, 15, 22}), {1, 0, 0}, axis);
        const auto removed = kernels::sweep_tri_dexel(stock, tool, &ch, 1);
        for (int f = 0; f < 3; ++f) {
            INFO("family " << "xyz"[f]);
            CHECK(removed[f] == Approx(area * 40).epsilon(0.005));
        }
    }
    SECTION("along the lean (along Y), in two chords") {
        auto stock = kernels::make_tri_dexel_box({0, 0, 0}, {30, 40, 20}, kCellMm);
        const ToolChord ch[2] = {chord(tip_for_centre({15, -5, 22}), tip_for_centre({15, 20, 22}), {1, 0, 0}, axis),
                                 chord(tip_for_centre({15, 20, 22}), tip_for_centre({15, 45, 22}), {1, 0, 0}, axis)};
        const auto removed = kernels::sweep_tri_dexel(stock, tool, ch, 2);
        for (int f = 0; f < 3; ++f) {
            INFO("family " << "xyz"[f]);
            CHECK(removed[f] == Approx(area * 40).epsilon(0.005));
        }
    }
}

TEST_CASE("tri-dexel: a horizontal ball end mill cuts a groove under an overhang (S3)", "[tri_dexel]") {
    // First a horizontal flat slot into the face x = 0 (depth 5, z 6..14) leaves an overhang: the
    // material above z = 14 hangs over the slot. Then a horizontal ball end mill R 2, centred at
    // z = 8 and x = 4 (its tip at x = 6), runs along the slot's back wall: a groove that is the
    // circular segment of height 1, under material on both sides.
    auto stock = kernels::make_tri_dexel_box({0, 0, 0}, {30, 40, 20}, kCellMm);
    const auto flat = solid_of(force_model::corner_radius_profile(8, 0, 20));
    const ToolChord slot = chord({5, -10, 10}, {5, 50, 10}, {0, 0, 1}, {-1, 0, 0});
    const auto first = kernels::sweep_tri_dexel(stock, flat, &slot, 1);
    for (int f = 0; f < 3; ++f) CHECK(first[f] == Approx(8 * 5 * 40).epsilon(0.005));

    const auto ball = solid_of(force_model::corner_radius_profile(4, 2, 20));
    const ToolChord groove = chord({6, -10, 8}, {6, 50, 8}, {0, 0, 1}, {-1, 0, 0});
    const auto second = kernels::sweep_tri_dexel(stock, ball, &groove, 1);
    // The X and Z rays cross the groove's section and measure it along their length; the Y rays
    // run along the groove, so they count the section's area in whole cells (2.5 mm^2 is 246
    // cells of 0.1 mm: a couple of cells off on its 7.7 mm outline is 1 %).
    CHECK(second[0] == Approx(segment_area(2, 1) * 40).epsilon(0.005));
    CHECK(second[2] == Approx(segment_area(2, 1) * 40).epsilon(0.005));
    CHECK(second[1] == Approx(segment_area(2, 1) * 40).epsilon(0.02));
    // A Z ray through the groove (x 5.45) holds the floor, air, the wall above the groove and the
    // overhang: material below the groove, then from the groove's top up.
    const auto& fz = stock.family[2];   // rays along z, grid over (x, y)
    const float* ray = fz.ray(std::size_t(200) * fz.nu + 54);   // x 5.45, y 20.05
    const double half = std::sqrt(4 - (5.45 - 4) * (5.45 - 4));
    CHECK(ray[0] == Approx(0).margin(1e-6));
    // The ball is a polygon inscribed within the sagitta; the ray meets it at 46 deg to the normal.
    CHECK(ray[kernels::kDexelIntervals] == Approx(8 - half).margin(2 * kSagittaMm));
    CHECK(ray[1] == Approx(8 + half).margin(2 * kSagittaMm));
    CHECK(ray[kernels::kDexelIntervals + 1] == Approx(20).margin(1e-6));
    // The X ray at z 8.05 starts at the groove's bottom, x = 4 + sqrt(4 - 0.05^2).
    const auto& fx = stock.family[0];   // grid over (y, z)
    CHECK(fx.ray(std::size_t(80) * fx.nu + 200)[0] == Approx(4 + std::sqrt(4 - 0.05 * 0.05)).margin(2e-3));
}
