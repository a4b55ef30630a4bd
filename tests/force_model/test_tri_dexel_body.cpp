// The shank and the holder against the tri-dexel stock for a tool at any orientation
// (docs/five_axis.md section 6, document 004): contact (material inside the shank or the holder)
// and the near-miss clearance within the shell, each against a closed form.
//   H1: a vertical holder over a flat top: face height minus the top, exactly (Z rays meet it).
//   H2: a holder leaning 60 deg beside a wall x = x_w: x_w minus the holder's largest x, which is
//       the far end's rim at R_h cos 60 deg beyond its centre; exact where an X ray passes that point.
//   H3: a holder in a hole 1 mm wider all round: 1 mm, no contact; a holder over a pocket: the
//       distance to the pocket's rim.
// Then end to end through predict_turning: a leaning ball end mill whose holder passes over the
// block's top flags holder_near_miss with the closed-form clearance, or holder_contact when it
// dips into it, on every device.
#include "force_model/force_model.hpp"
#include "force_model/motion_fixtures.hpp"
#include "force_model/reference.hpp"
#include "kernels/tri_dexel.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <numbers>
#include <string>

using namespace cutload;

namespace {

using Vec = std::array<double, 3>;
using Mat = std::array<Vec, 3>;

const Mat kVertical{{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}};

// The tool leaning `lean_deg` from +Z toward +X: columns x (cos, 0, -sin), y, z (sin, 0, cos).
Mat leaning(double lean_deg) {
    const double l = lean_deg * std::numbers::pi / 180;
    return {{{std::cos(l), 0, std::sin(l)}, {0, 1, 0}, {-std::sin(l), 0, std::cos(l)}}};
}

// A flat-bottomed cylinder of radius r, 100 mm tall, for plunging holes.
kernels::ConvexToolSolid cylinder(double r_mm) {
    return kernels::convex_tool_solid({{0, 0}, {r_mm, 0}, {r_mm, 100}});
}

// Plunges the cylinder along Z at (x, y) from above the box down to z_bottom.
void plunge(kernels::TriDexel& s, double r_mm, double x_mm, double y_mm, double z_bottom_mm) {
    kernels::ToolChord c;
    c.from_mm = {x_mm, y_mm, s.hi_mm[2] + 1};
    c.to_mm = {x_mm, y_mm, z_bottom_mm};
    c.rot = kVertical;
    kernels::sweep_tri_dexel(s, cylinder(r_mm), &c, 1);
}

}  // namespace

TEST_CASE("H1: a vertical holder over a flat top, and the shank and holder in a hole", "[tri_dexel][holder]") {
    // Box 40 x 40 x 20 (top z 0) with a D8.4 hole 12 deep at the origin.
    kernels::TriDexel s = kernels::make_tri_dexel_box({-20, -20, -20}, {20, 20, 0}, 0.1);
    plunge(s, 4.2, 0, 0, -12);
    kernels::ToolBody b;
    b.flute_length_mm = 10, b.stickout_mm = 12, b.holder_length_mm = 30;
    b.shank_radius_mm = 4, b.holder_radius_mm = 10;

    // Tip 10 deep: the shank stands in the hole's air above the flutes, the face 2 mm over the top.
    const auto over = kernels::tri_dexel_body_clearance(s, {0, 0, -10}, kVertical, b, 3);
    CHECK_FALSE(over.contact);
    CHECK(over.clearance_mm == Approx(2.0).margin(1e-9));
    const auto thin = kernels::tri_dexel_body_clearance(s, {0, 0, -10}, kVertical, b, 1.5);
    CHECK_FALSE(thin.contact);
    CHECK(std::isinf(thin.clearance_mm));   // 2 mm away is outside a 1.5 mm shell
    // Half a millimetre deeper than the hole: the face is 0.5 mm into the top.
    CHECK(kernels::tri_dexel_body_clearance(s, {0, 0, -12.5}, kVertical, b, 3).contact);
    // Tip 11.5 deep: the shank's lowest 1.5 mm are in the hole, the face 0.5 mm over the top. A
    // shank 8 mm across clears the 8.4 mm hole; one 9 mm across rubs its wall.
    const auto low = kernels::tri_dexel_body_clearance(s, {0, 0, -11.5}, kVertical, b, 3);
    CHECK_FALSE(low.contact);
    CHECK(low.clearance_mm == Approx(0.5).margin(1e-9));
    kernels::ToolBody wide = b;
    wide.shank_radius_mm = 4.5;
    CHECK(kernels::tri_dexel_body_clearance(s, {0, 0, -11.5}, kVertical, wide, 0).contact);
    // Outside the box altogether: nothing.
    const auto away = kernels::tri_dexel_body_clearance(s, {0, 0, 60}, kVertical, b, 3);
    CHECK_FALSE(away.contact);
    CHECK(std::isinf(away.clearance_mm));
}

TEST_CASE("H2: a holder leaning 60 deg beside a wall is its largest x away from it", "[tri_dexel][holder]") {
    // The wall block x 30..40; X rays at y = -20 + (i + 1/2) 0.1, z = -10 + (j + 1/2) 0.1.
    const double x_w = 30;
    kernels::TriDexel s = kernels::make_tri_dexel_box({x_w, -20, -10}, {40, 20, 40}, 0.1);
    kernels::ToolBody b;
    b.flute_length_mm = 10, b.stickout_mm = 20, b.holder_length_mm = 20;
    b.shank_radius_mm = 3, b.holder_radius_mm = 8;
    const double lean = 60 * std::numbers::pi / 180;
    const Mat rot = leaning(60);
    // The holder's largest x: the far end's centre (tip + 40 along the axis) plus R_h along the
    // tool's x, which leans down the wall: x_e = tip_x + 40 sin 60 + 8 cos 60, z_e = tip_z + 40 cos 60 - 8 sin 60.
    const double top_mm = b.stickout_mm + b.holder_length_mm;
    const double dx = top_mm * std::sin(lean) + b.holder_radius_mm * std::cos(lean);
    const double dz = top_mm * std::cos(lean) - b.holder_radius_mm * std::sin(lean);
    // Place that point on the X ray (y 0.05, z 10.05), 1.25 mm from the wall.
    const Vec tip{x_w - 1.25 - dx, 0.05, 10.05 - dz};
    const auto r = kernels::tri_dexel_body_clearance(s, tip, rot, b, 2);
    CHECK_FALSE(r.contact);
    CHECK(r.clearance_mm == Approx(1.25).margin(1e-6));
    // Off the ray by half a cell in y the nearest ray sees the rim's curve: still within 2e-4 mm.
    const auto r_off = kernels::tri_dexel_body_clearance(s, {tip[0], tip[1] + 0.05, tip[2]}, rot, b, 2);
    CHECK(r_off.clearance_mm >= 1.25 - 1e-6);
    CHECK(r_off.clearance_mm == Approx(1.25).margin(2e-4));
    // A shell thinner than the gap sees nothing; half a millimetre into the wall is contact.
    CHECK(std::isinf(kernels::tri_dexel_body_clearance(s, tip, rot, b, 1.2).clearance_mm));
    CHECK(kernels::tri_dexel_body_clearance(s, {tip[0] + 1.75, tip[1], tip[2]}, rot, b, 2).contact);
    CHECK_FALSE(kernels::tri_dexel_body_clearance(s, {tip[0] + 1.24, tip[1], tip[2]}, rot, b, 2).contact);
}

TEST_CASE("H3: a holder in a hole 1 mm wider all round, and over a pocket", "[tri_dexel][holder]") {
    kernels::TriDexel s = kernels::make_tri_dexel_box({-30, -30, -30}, {30, 30, 0}, 0.1);
    plunge(s, 17, 0, 0, -40);   // through
    kernels::ToolBody b;
    b.flute_length_mm = 10, b.stickout_mm = 15, b.holder_length_mm = 40;
    b.shank_radius_mm = 4, b.holder_radius_mm = 16;
    // Down in the hole: the holder's side 1 mm from its wall everywhere (the X and Y rays end on
    // the wall at radius 17 exactly).
    const auto in_gap = kernels::tri_dexel_body_clearance(s, {0, 0, -25}, kVertical, b, 2);
    CHECK_FALSE(in_gap.contact);
    CHECK(in_gap.clearance_mm == Approx(1.0).margin(1e-5));
    CHECK(std::isinf(kernels::tri_dexel_body_clearance(s, {0, 0, -25}, kVertical, b, 0.5).clearance_mm));
    // Off centre by 1.5 mm: the side enters the wall.
    CHECK(kernels::tri_dexel_body_clearance(s, {1.5, 0, -25}, kVertical, b, 2).contact);
    // Raised so the face is 3 mm over the top: the nearest material is the hole's rim, 1 mm out and
    // 3 mm down from the face's edge; rays reach the rim within their spacing.
    const auto rim = kernels::tri_dexel_body_clearance(s, {0, 0, -12}, kVertical, b, 4);
    CHECK_FALSE(rim.contact);
    CHECK(rim.clearance_mm >= std::hypot(1.0, 3.0) - 1e-6);
    CHECK(rim.clearance_mm == Approx(std::hypot(1.0, 3.0)).margin(0.01));
    CHECK(std::isinf(kernels::tri_dexel_body_clearance(s, {0, 0, -12}, kVertical, b, 2).clearance_mm));
}

namespace {

// A D10 ball end mill leaning 30 deg toward +X, 1 mm into the top of the block x 0..40,
// y -15..35, z -20..0, run along Y at x 10. Its holder (D30) has its face centre at tip + s a; the
// face's lowest point is R_h sin 30 below that, at x tip + s sin 30 + R_h cos 30 = 30 for s 14.
std::string spec_text(double flute_mm, double stickout_mm, double clearance_mm) {
    return R"json({
  "tool": {"shape": "ball", "diameter_mm": 10, "flutes": 2, "helix_deg": 30, "corner_radius_mm": 5,
           "flute_length_mm": )json" +
           std::to_string(flute_mm) + R"json(, "stickout_mm": )json" + std::to_string(stickout_mm) +
           R"json(, "holder": {"diameter_mm": 30, "length_mm": 40}},
  "material": {"name": "test", "Ktc_N_mm2": 700, "Krc_N_mm2": 210, "Kac_N_mm2": 120,
               "Kte_N_mm": 20, "Kre_N_mm": 28, "Kae_N_mm": 2},
  "stock": {"box_mm": {"min": [0, -15, -20], "max": [40, 35, 0]}},
  "resolution": {"angle_step_deg": 2, "axial_step_mm": 0.2, "grid_mm": 0.2},
  "limits": {"holder_clearance_mm": )json" +
           std::to_string(clearance_mm) + "}\n}";
}

force_model::Prediction run_along_y(double flute_mm, double stickout_mm, double clearance_mm, force_model::Device d,
                                    double x_mm = 10, double z_mm = -1) {
    testref::Path path;
    path.start_mm = {x_mm, -25, z_mm};
    path.segments = {testref::line_to({x_mm, 45, z_mm}, "N10")};
    path.feed_mm_min = 3000;
    path.spindle_rpm = 10000;
    const motion_io::MotionModel motion = testref::uniform_motion(path);
    force_model::ToolPoses poses;
    const Mat rot = leaning(30);
    force_model::Rotation3 r;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) r.m[std::size_t(3 * i + j)] = rot[std::size_t(i)][std::size_t(j)];
    poses.tool_to_stock.assign(motion.size(), r);
    poses.omega_tool_rad_s.assign(motion.size(), {0, 0, 0});
    const auto spec = force_model::parse_run_spec_text(spec_text(flute_mm, stickout_mm, clearance_mm), "holder.json");
    force_model::PredictOptions opt;
    opt.device = d;
    return force_model::predict_turning(motion, poses, spec, opt);
}

const force_model::FlagHit* flag(const force_model::Prediction& p, const std::string& name) {
    for (const auto& b : p.blocks)
        for (const auto& f : b.flags)
            if (f.flag == name) return &f;
    return nullptr;
}

}  // namespace

TEST_CASE("predict_turning flags a leaning holder's near miss and contact with the closed-form clearance",
          "[tri_dexel][turning][holder]") {
    const double lean = 30 * std::numbers::pi / 180;
    for (const force_model::Device d : testref::devices_under_test()) {
        INFO(testref::device_name(d));
        // Face centre 14 mm up the axis: its lowest point at z -1 + 14 cos 30 - 15 sin 30 over the top (z 0).
        const double clearance = -1 + 14 * std::cos(lean) - 15 * std::sin(lean);
        const auto near = run_along_y(10, 14, 4, d);
        const force_model::FlagHit* hit = flag(near, "holder_near_miss");
        REQUIRE(hit != nullptr);
        // Z rays lie within 0.1 mm of the face's lowest point: the distance grows with its square.
        CHECK(hit->value >= clearance - 1e-5);
        CHECK(hit->value == Approx(clearance).margin(2e-3));
        CHECK(flag(near, "holder_contact") == nullptr);
        // A near miss, never contact, on any row.
        std::size_t flagged = 0;
        for (const auto& row : near.samples) flagged += row.holder_contact ? 1 : 0;
        CHECK(flagged == 0);
        // A 3 mm shell: no near miss, and the forces are the same with the check as without.
        const auto off = run_along_y(10, 14, 3, d);
        CHECK(flag(off, "holder_near_miss") == nullptr);
        REQUIRE(off.samples.size() == near.samples.size());
        for (std::size_t i = 0; i < off.samples.size(); i += 101) CHECK(off.samples[i].fx_N == near.samples[i].fx_N);
        // Face 8 mm up: its lowest point 1.57 mm into the top. Contact, on rows too.
        const auto dips = run_along_y(6, 8, 4, d);
        CHECK(flag(dips, "holder_contact") != nullptr);
        std::size_t touching = 0;
        for (const auto& row : dips.samples) touching += row.holder_contact ? 1 : 0;
        CHECK(touching > dips.samples.size() / 2);
        // Beside the block (tip at x -12, z -8), the flutes never reach it, but the holder leans
        // over it: its lowest point (x -12 + 7 + 15 cos 30 = 8, z -8 + 14 cos 30 - 7.5 = -3.4) is
        // inside. Contact, with no cutting at all.
        const auto beside = run_along_y(10, 14, 4, d, -12, -8);
        CHECK(beside.stats.cutting_steps == 0);
        CHECK(flag(beside, "holder_contact") != nullptr);
    }
}
