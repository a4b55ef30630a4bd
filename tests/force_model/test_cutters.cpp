// The cutter geometry module (force_model/cutters/): profiles built from segments, their edge
// elements and lower surfaces, against the closed forms of each shape's geometry.
#include "force_model/cutters/barrel.hpp"
#include "force_model/cutters/shapes.hpp"
#include "force_model/force_model.hpp"
#include "force_model/cutters/tool_geometry.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <numbers>
#include <stdexcept>

using namespace cutload;
using namespace cutload::force_model;

namespace {

constexpr double kPi = std::numbers::pi;

Cutter cutter_of(CutterProfile profile, int flutes = 2, double helix_deg = 30) {
    return Cutter{std::move(profile), flutes, helix_deg, 30, 32, 40};
}

// Sums over the edge elements whose axial span ends at or below z_mm: sum of db, of r nr db (the
// element's share of the chip cross-section per unit feed, doubled over both sides), of r db.
struct ElementSums {
    double length_mm = 0, area_mm2 = 0, moment_mm2 = 0;
    int count = 0;
};
ElementSums sums_below(const kernels::EdgeTable& t, double z_mm) {
    ElementSums s;
    for (std::size_t e = 0; e < t.size(); ++e) {
        if (t.z_hi_mm[e] > z_mm + 1e-9) continue;
        s.length_mm += t.db_mm[e];
        s.area_mm2 += 2 * t.r_mm[e] * t.nr[e] * t.db_mm[e];
        s.moment_mm2 += t.r_mm[e] * t.db_mm[e];
        ++s.count;
    }
    return s;
}

}  // namespace

TEST_CASE("cutters: a cone tip's elements and lower surface follow the cone", "[cutters]") {
    // Spot drill / chamfer mill: D 8, 90 deg point (flank at 45 deg to the axis), sharp tip, the
    // cone meeting the diameter 4 mm above the tip, then the cylinder to 20 mm.
    const CutterProfile cone = cone_profile(8, 0, 90, 20);
    CHECK(cone.radius_mm() == Approx(4));
    CHECK(cone.length_mm() == Approx(20));
    for (double r : {0.0, 0.5, 1.7, 3.2, 4.0}) CHECK(cone.lower_surface_mm(r) == Approx(r).margin(1e-12));

    const ToolGeometry g = build_tool_geometry(cutter_of(cone), 0.1);
    const kernels::EdgeTable& t = g.edges;
    CHECK(t.bottom_count == 0);   // no flat: nothing waits for a descending tool
    for (std::size_t e = 1; e < t.size(); ++e) CHECK(t.z_lo_mm[e] >= t.z_lo_mm[e - 1]);   // sorted by height
    // Every cone element: normal at 45 deg down and out, radius = height (tan 45 deg).
    const ElementSums cone_part = sums_below(t, 4.0);
    REQUIRE(cone_part.count > 0);
    for (int e = 0; e < cone_part.count; ++e) {
        CHECK(t.nr[e] == Approx(std::sqrt(0.5)));
        CHECK(t.nz[e] == Approx(-std::sqrt(0.5)));
        CHECK(t.r_mm[e] == Approx(t.z_mm[e]));
        CHECK(t.lag_rad[e] == Approx(t.z_mm[e] * std::tan(30 * kPi / 180) / 4));
    }
    // Closed forms for the part below depth a = 4 mm (the whole cone), flank angle theta 45 deg:
    // slant length a / cos(theta); V-groove cross-section 2 * integral of r dz = a^2 tan(theta);
    // integral of r ds = a^2 tan(theta) / (2 cos(theta)).
    const double a = 4, theta = kPi / 4;
    CHECK(cone_part.length_mm == Approx(a / std::cos(theta)).epsilon(1e-12));
    CHECK(cone_part.area_mm2 == Approx(a * a * std::tan(theta)).epsilon(1e-12));
    CHECK(cone_part.moment_mm2 == Approx(a * a * std::tan(theta) / (2 * std::cos(theta))).epsilon(1e-12));
    // The lower-surface table the removal kernels interpolate is the cone itself.
    for (std::size_t k = 0; k < g.lower_mm.size(); ++k)
        CHECK(g.lower_mm[k] == Approx(4.0 * double(k) / double(g.lower_mm.size() - 1)).margin(1e-12));
}

TEST_CASE("cutters: a drill point, a chamfer with a flat tip and a taper are cones too", "[cutters]") {
    // 118 deg twist drill D 10: the cone is R / tan(59 deg) high.
    const CutterProfile drill = cone_profile(10, 0, 118, 40);
    CHECK(drill.lower_surface_mm(5) == Approx(5 / std::tan(59 * kPi / 180)));
    CHECK(drill.lower_surface_mm(2) == Approx(2 / std::tan(59 * kPi / 180)));
    // Chamfer mill D 12 with a 2 mm flat: the flat is the bottom, then the cone from r = 1.
    const ToolGeometry chamfer = build_tool_geometry(cutter_of(cone_profile(12, 2, 90, 10)), 0.1);
    CHECK(chamfer.edges.bottom_count == 10);
    CHECK(chamfer.lower_mm.front() == 0);
    CHECK(chamfer.lower_mm.back() == Approx(5));
    // Tapered flank: 5 mm flat tip widening by 2 deg per side over 20 mm of flutes (a 4 deg
    // "point"), reaching the diameter at the end of the flutes.
    const double taper_deg = 2, tip_d = 5, L = 20;
    const double D = tip_d + 2 * L * std::tan(taper_deg * kPi / 180);
    const CutterProfile taper = cone_profile(D, tip_d, 2 * taper_deg, L);
    CHECK(taper.radius_mm() == Approx(D / 2));
    CHECK(taper.length_mm() == Approx(L));
    CHECK(taper.lower_surface_mm(tip_d / 2 + 0.5) == Approx(0.5 / std::tan(taper_deg * kPi / 180)));
    CHECK_THROWS_WITH(cone_profile(8, 0, 90, 3), Catch::Contains("beyond the flute length"));
    CHECK_THROWS_WITH(cone_profile(8, 0, 180, 30), Catch::Contains("point angle"));
}

TEST_CASE("cutters: flat, ball and bull-nose profiles match their closed forms", "[cutters]") {
    const double R = 4, L = 20;
    SECTION("bull nose, corner radius 1.5") {
        const double rc = 1.5, a = R - rc;
        const CutterProfile bull = corner_radius_profile(2 * R, rc, L);
        for (double r : {0.0, 1.0, a, a + 0.3, a + 1.2, R})
            CHECK(bull.lower_surface_mm(r) ==
                  Approx(r <= a ? 0.0 : rc - std::sqrt(rc * rc - (r - a) * (r - a))).margin(1e-12));
        const ToolGeometry g = build_tool_geometry(cutter_of(bull), 0.1);
        CHECK(g.edges.bottom_count == 25);   // a / 0.1
        // Edge length: flat + quarter arc + cylinder.
        const ElementSums all = sums_below(g.edges, L);
        CHECK(all.length_mm == Approx(a + kPi / 2 * rc + (L - rc)).epsilon(1e-12));
        // Below the corner (z <= rc): projected area 2 * integral of r dz over the arc,
        // 2 * [a rc + rc^2 pi / 4].
        CHECK(sums_below(g.edges, rc).area_mm2 == Approx(2 * (a * rc + rc * rc * kPi / 4)).epsilon(2e-3));
    }
    SECTION("ball") {
        const CutterProfile ball = corner_radius_profile(2 * R, R, L);
        CHECK(ball.lower_surface_mm(0) == 0);
        CHECK(ball.lower_surface_mm(R) == Approx(R));
        CHECK(ball.lower_surface_mm(2) == Approx(R - std::sqrt(R * R - 4)));
        // A ball with flutes on the ball only ends exactly at its radius's height.
        CHECK(corner_radius_profile(2 * R, R, R).length_mm() == R);
        const ToolGeometry g = build_tool_geometry(cutter_of(ball), 0.1);
        CHECK(g.edges.bottom_count == 0);
        for (std::size_t e = 0; e < g.edges.size(); ++e)   // normals of unit length, pointing out and down
            CHECK(std::hypot(g.edges.nr[e], g.edges.nz[e]) == Approx(1));
    }
    SECTION("flat") {
        const ToolGeometry g = build_tool_geometry(cutter_of(corner_radius_profile(2 * R, 0, L)), 0.1);
        CHECK(g.edges.bottom_count == 40);
        CHECK(g.edges.size() == 40 + 200);
        for (double v : g.lower_mm) CHECK(v == 0);
    }
}

TEST_CASE("cutters: a barrel profile (document 003) is a chain of arcs", "[cutters]") {
    // Suzuki & Morishige's barrel tool: tool radius r = 3, barrel arc r1 = 96, tip ball r2 = 1
    // (centre on the axis, 1 mm above the tip). The barrel arc touches the tip ball from inside, so
    // its centre lies across the axis at r - r1 = -93, at the height where the centres are
    // r1 - r2 apart; the two arcs share the normal where they meet.
    const double r = 3, r1 = 96, r2 = 1;
    const double centre_r = r - r1, centre_z = r2 + std::sqrt((r1 - r2) * (r1 - r2) - centre_r * centre_r);
    const double kappa_joint = std::asin(-centre_r / (r1 - r2));
    const CutterProfile barrel({ArcSegment{0, r2, r2, 0, kappa_joint}, ArcSegment{centre_r, centre_z, r1, kappa_joint, kPi / 2}});
    CHECK(barrel.radius_mm() == Approx(r));
    CHECK(barrel.length_mm() == Approx(centre_z));
    CHECK(barrel.lower_surface_mm(0.5) == Approx(r2 - std::sqrt(r2 * r2 - 0.25)));
    CHECK(barrel.lower_surface_mm(r) == Approx(centre_z));
    const double r_mid = 2.5;   // on the barrel arc
    CHECK(barrel.lower_surface_mm(r_mid) == Approx(centre_z - std::sqrt(r1 * r1 - (r_mid - centre_r) * (r_mid - centre_r))));
    const ToolGeometry g = build_tool_geometry(cutter_of(barrel), 0.2);
    CHECK(sums_below(g.edges, g.flute_length_mm).length_mm == Approx(r2 * kappa_joint + r1 * (kPi / 2 - kappa_joint)));
}

TEST_CASE("cutters: barrel_profile builds document 003's barrel from r, r1 and r2", "[cutters][barrel]") {
    const double r = 3, r1 = 96, r2 = 1;
    // docs/five_axis.md §5.2, by hand: z_b = 1 + sqrt(95^2 - 93^2) = 1 + sqrt(376) = 20.391 mm; the
    // arc meets the ball at (0.979, 0.796) mm.
    const double z_b = 1 + std::sqrt(376.0);
    CHECK(barrel_widest_height_mm(2 * r, r1, r2) == Approx(z_b).epsilon(1e-14));
    const CutterProfile p = barrel_profile(2 * r, r1, r2, z_b);
    REQUIRE(p.segments().size() == 2);
    CHECK(p.radius_mm() == Approx(r).epsilon(1e-14));
    CHECK(p.length_mm() == Approx(z_b).epsilon(1e-14));
    const ProfilePoint joint = segment_end(p.segments()[0]);
    CHECK(joint.r_mm == Approx(93.0 / 95).epsilon(1e-12));
    CHECK(joint.z_mm == Approx(1 - std::sqrt(376.0) / 95).epsilon(1e-12));
    CHECK(joint.z_mm == Approx(0.796).margin(5e-4));
    // Every flank element sits on the circle of radius r1 about (r - r1, z_b), normal along the radius.
    const ToolGeometry g = build_tool_geometry(cutter_of(p), 0.1);
    int on_arc = 0;
    for (std::size_t e = 0; e < g.edges.size(); ++e) {
        const double u = g.edges.r_mm[e] - (r - r1), w = g.edges.z_mm[e] - z_b;
        if (g.edges.z_mm[e] < joint.z_mm) continue;
        ++on_arc;
        CHECK(std::hypot(u, w) == Approx(r1).epsilon(1e-12));
        CHECK(g.edges.nr[e] == Approx(u / r1).epsilon(1e-12));
        CHECK(g.edges.nz[e] == Approx(w / r1).margin(1e-12));
    }
    CHECK(on_arc == int(std::ceil(r1 * (kPi / 2 - std::asin(93.0 / 95)) / 0.1)));
    // Longer flutes continue as a cylinder of the widest radius, tangent to the arc's top.
    const CutterProfile longer = barrel_profile(2 * r, r1, r2, 30);
    REQUIRE(longer.segments().size() == 3);
    CHECK(longer.length_mm() == 30);
    CHECK(longer.radius_mm() == Approx(r).epsilon(1e-14));
    CHECK(longer.lower_surface_mm(2.5) == Approx(z_b - std::sqrt(r1 * r1 - (2.5 - (r - r1)) * (2.5 - (r - r1)))));
    // Inconsistent numbers are refused: r1 not past r, r2 not inside r, flutes short of the widest point.
    CHECK_THROWS_AS(barrel_profile(6, 3, 1, 30), std::invalid_argument);
    CHECK_THROWS_AS(barrel_profile(6, 96, 3, 30), std::invalid_argument);
    CHECK_THROWS_AS(barrel_profile(6, 96, 0, 30), std::invalid_argument);
    CHECK_THROWS_AS(barrel_profile(6, 96, 1, 20), std::invalid_argument);
}

TEST_CASE("cutters: the pick feed for a 5 um cusp is 1.960 mm under document 003's barrel, 0.346 mm under a 3 mm ball",
          "[cutters][barrel]") {
    // Figures of docs/five_axis.md §5.2 (issue 15): 2 sqrt(0.005 x 191.995) and 2 sqrt(0.005 x 5.995).
    CHECK(pick_feed_mm(96, 0.005) == Approx(1.959566).margin(5e-7));
    CHECK(std::round(pick_feed_mm(96, 0.005) * 1000) / 1000 == 1.960);
    CHECK(pick_feed_mm(3, 0.005) == Approx(0.346266).margin(5e-7));
    // The inverse: the cusp between two circles of radius r1, s apart, is r1 - sqrt(r1^2 - s^2 / 4).
    for (double rho : {0.5, 3.0, 96.0, 1500.0})
        for (double h : {1e-4, 0.005, 0.1}) {
            if (h > rho) continue;
            const double s = pick_feed_mm(rho, h);
            CHECK(rho - std::sqrt(rho * rho - s * s / 4) == Approx(h).epsilon(1e-9));
        }
    CHECK(pick_feed_mm(2, 2) == Approx(4));   // a cusp as deep as the radius: circles side by side
    CHECK_THROWS_AS(pick_feed_mm(96, 0), std::invalid_argument);
    CHECK_THROWS_AS(pick_feed_mm(96, -0.005), std::invalid_argument);
    CHECK_THROWS_AS(pick_feed_mm(3, 3.5), std::invalid_argument);
    CHECK_THROWS_AS(pick_feed_mm(0, 0.005), std::invalid_argument);
}

TEST_CASE("cutters: a broken profile is refused, naming the segment", "[cutters]") {
    CHECK_THROWS_WITH(CutterProfile({LineSegment{{1, 0}, {4, 0}}}), Catch::Contains("segment 0") && Catch::Contains("tip"));
    CHECK_THROWS_WITH(CutterProfile({LineSegment{{0, 0}, {4, 0}}, LineSegment{{4, 1}, {4, 20}}}),
                      Catch::Contains("segment 1") && Catch::Contains("does not start where"));
    CHECK_THROWS_WITH(CutterProfile({LineSegment{{0, 0}, {4, 2}}, LineSegment{{4, 2}, {5, 1}}}),
                      Catch::Contains("segment 1") && Catch::Contains("z falls"));
    CHECK_THROWS_WITH(CutterProfile({ArcSegment{0, 1, 1, 0, 4}}), Catch::Contains("segment 0") && Catch::Contains("arc angles"));
    CHECK_THROWS_AS(CutterProfile({}), std::invalid_argument);
}

TEST_CASE("cutters: tapered flat, ball and bull end mills widen by tan(taper) per mm from the tip's diameter", "[cutters]") {
    const double R = 4, L = 20, beta_deg = 3, beta = beta_deg * kPi / 180;
    SECTION("taper 0 is the untapered profile exactly") {
        for (double rc : {0.0, 1.5, R}) {
            const CutterProfile a = corner_radius_profile(2 * R, rc, L), b = tapered_end_mill_profile(2 * R, rc, 0, L);
            REQUIRE(a.segments().size() == b.segments().size());
            const ToolGeometry ga = build_tool_geometry(cutter_of(a), 0.1), gb = build_tool_geometry(cutter_of(b), 0.1);
            CHECK(ga.edges.r_mm == gb.edges.r_mm);
            CHECK(ga.edges.z_mm == gb.edges.z_mm);
            CHECK(ga.edges.nr == gb.edges.nr);
            CHECK(ga.edges.db_mm == gb.edges.db_mm);
            CHECK(ga.edges.lag_rad == gb.edges.lag_rad);
            CHECK(ga.lower_mm == gb.lower_mm);
        }
    }
    SECTION("flat: the flank from the bottom's edge, normal (cos, -sin) of the taper") {
        const CutterProfile p = tapered_end_mill_profile(2 * R, 0, beta_deg, L);
        CHECK(p.radius_mm() == Approx(R + L * std::tan(beta)).epsilon(1e-12));
        CHECK(p.length_mm() == L);
        const ToolGeometry g = build_tool_geometry(cutter_of(p), 0.1);
        CHECK(g.edges.bottom_count == 40);
        for (std::size_t e = std::size_t(g.edges.bottom_count); e < g.edges.size(); ++e) {
            CHECK(g.edges.r_mm[e] == Approx(R + g.edges.z_mm[e] * std::tan(beta)).epsilon(1e-12));
            CHECK(g.edges.nr[e] == Approx(std::cos(beta)));
            CHECK(g.edges.nz[e] == Approx(-std::sin(beta)));
        }
        // Edge length of the flank: L / cos(beta).
        CHECK(sums_below(g.edges, L).length_mm == Approx(R + L / std::cos(beta)).epsilon(1e-12));
        for (double r : {0.0, 2.0, R}) CHECK(p.lower_surface_mm(r) == 0);
        CHECK(p.lower_surface_mm(R + 0.5) == Approx(0.5 / std::tan(beta)));
    }
    SECTION("ball and bull: the arc meets the flank tangentially") {
        for (double rc : {1.5, R}) {
            const CutterProfile p = tapered_end_mill_profile(2 * R, rc, beta_deg, L);
            const auto& arc = std::get<ArcSegment>(p.segments()[rc < R ? 1 : 0]);
            CHECK(arc.to_rad == Approx(kPi / 2 - beta));
            const auto& flank = std::get<LineSegment>(p.segments().back());
            const ProfilePoint end = arc.at(arc.to_rad);
            CHECK(flank.from.r_mm == end.r_mm);
            CHECK(flank.from.z_mm == end.z_mm);
            CHECK((flank.to.r_mm - flank.from.r_mm) / (flank.to.z_mm - flank.from.z_mm) == Approx(std::tan(beta)));
            // The flank's line passes the arc's centre at distance rc (tangent), and at z = rc it is
            // rc / cos(beta) out from the centre.
            CHECK(tapered_flank_radius_mm(2 * R, rc, beta_deg, rc) == Approx(R - rc + rc / std::cos(beta)).epsilon(1e-12));
        }
    }
    SECTION("refused: a taper of 45 degrees or more is a cone") {
        CHECK_THROWS_AS(tapered_end_mill_profile(2 * R, 0, 45, L), std::invalid_argument);
        CHECK_THROWS_AS(tapered_end_mill_profile(2 * R, 0, -1, L), std::invalid_argument);
    }
}
