// The OpenCL kernels of the multi-direction stock (kernels/tri_dexel.cl) against their scalar twins
// (kernels/tri_dexel.cpp): the same pose engine run on both backends along a path that leans and
// turns the tool while it cuts into, across and out of a block. Step by step the forces, moments
// and engaged extents, the removed volumes and every ray of the three families must agree; the
// kernels are double precision, so they agree far inside the 0.5 %.
#include "force_model/cutters/shapes.hpp"
#include "force_model/cutters/tool_geometry.hpp"
#include "force_model/engine/pose_backend.hpp"
#include "force_model/engine/pose_engine.hpp"
#include "force_model/reference.hpp"
#include "kernels/tri_dexel.hpp"

#include <catch2/catch.hpp>
#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

using namespace cutload;
using Vec = std::array<double, 3>;
using Mat = std::array<Vec, 3>;

namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kCellMm = 0.1;

// Rotation taking the tool's z to the direction with lead (about y) and tilt (about x), columns the
// tool's axes.
Mat lean(double lead_rad, double tilt_rad) {
    const double cl = std::cos(lead_rad), sl = std::sin(lead_rad), ct = std::cos(tilt_rad), st = std::sin(tilt_rad);
    // R = Rx(tilt) * Ry(lead)
    return {{{cl, 0, sl}, {st * sl, ct, -st * cl}, {-ct * sl, st, ct * cl}}};
}

Vec to_tool(const Mat& r, const Vec& v) {
    return {r[0][0] * v[0] + r[1][0] * v[1] + r[2][0] * v[2], r[0][1] * v[0] + r[1][1] * v[1] + r[2][1] * v[2],
            r[0][2] * v[0] + r[1][2] * v[1] + r[2][2] * v[2]};
}

struct Case {
    std::string name;
    force_model::CutterProfile profile;
    int flutes;
    double depth_mm;   // the tip below the block's top
};

// A path in three straight legs (in, across, out) with the lead swinging 0 -> 25 deg and back and the
// tilt -10 -> 15 deg, at 10 000 rpm, 2 deg a step.
std::vector<kernels::PoseStep> turning_path(const Case& c, const force_model::ToolGeometry& g) {
    const double rpm = 10000, step_deg = 2, feed_mm_min = 2400;
    const double dt_s = step_deg / (rpm * 6);
    const double v_mm_s = feed_mm_min / 60;
    const double per_tooth_s = 60 / (rpm * g.edges.flutes);
    const Vec a{-8, -3, -c.depth_mm}, b{14, 2, -c.depth_mm - 0.5}, e{26, 9, -c.depth_mm + 0.3};
    std::vector<kernels::PoseStep> steps;
    double t = 0;
    for (const auto& [p, q] : {std::pair{a, b}, std::pair{b, e}}) {
        const double len = std::hypot(q[0] - p[0], q[1] - p[1], q[2] - p[2]);
        const int n = int(len / v_mm_s / dt_s);
        const Vec vel{(q[0] - p[0]) / len * v_mm_s, (q[1] - p[1]) / len * v_mm_s, (q[2] - p[2]) / len * v_mm_s};
        for (int i = 0; i < n; ++i, t += dt_s) {
            const double u = double(i) / n;
            const double phase = t / 1.2;   // seconds of the whole path ~ 0.8 s
            const double lead = 25 * kPi / 180 * std::sin(kPi * phase), tilt = (-10 + 25 * phase) * kPi / 180;
            const double dlead = 25 * kPi / 180 * std::cos(kPi * phase) * kPi / 1.2, dtilt = 25 * kPi / 180 / 1.2;
            kernels::PoseStep s;
            s.tip_mm = {p[0] + u * (q[0] - p[0]), p[1] + u * (q[1] - p[1]), p[2] + u * (q[2] - p[2])};
            s.rot = lean(lead, tilt);
            s.feed_mm = to_tool(s.rot, {vel[0] * per_tooth_s, vel[1] * per_tooth_s, vel[2] * per_tooth_s});
            // Body rates of R = Rx(tilt) Ry(lead): omega = Ry^T (dtilt, 0, 0) + (0, dlead, 0).
            s.turn_rad = {std::cos(lead) * dtilt * per_tooth_s, dlead * per_tooth_s, std::sin(lead) * dtilt * per_tooth_s};
            s.theta_rad = 2 * kPi * rpm / 60 * t;
            steps.push_back(s);
        }
    }
    return steps;
}

}  // namespace

TEST_CASE("tri-dexel OpenCL: engagement and removal equal the scalar twins along a path that leans and turns the tool",
          "[tri_dexel][opencl]") {
    if (testref::devices_under_test().size() < 2) return;   // no OpenCL platform (it warns)
    const std::vector<Case> cases{
        {"ball D10", force_model::corner_radius_profile(10, 5, 20), 2, 2},
        {"bull D8 R1", force_model::corner_radius_profile(8, 1, 16), 3, 1.5},
        {"flat D6", force_model::corner_radius_profile(6, 0, 15), 4, 1},
        {"taper R1 3 deg", force_model::tapered_end_mill_profile(6, 1, 3, 15), 2, 2},
        {"barrel r 2 r1 40", force_model::barrel_profile(10, 40, 2, 20), 2, 1},
    };
    const testref::Coefficients k = testref::test_coefficients();
    for (const Case& c : cases) {
        SECTION(c.name) {
            const force_model::Cutter cutter{c.profile, c.flutes, 30, 30, 0, 0};
            const force_model::ToolGeometry g = force_model::build_tool_geometry(cutter, 0.05);
            kernels::EngageParams params;
            params.k = {k.Ktc_N_mm2, k.Krc_N_mm2, k.Kac_N_mm2, k.Kte_N_mm, k.Kre_N_mm, k.Kae_N_mm};
            params.element_end = int(g.edges.size());
            params.holder_face_z_mm = 30;
            std::vector<std::array<double, 2>> rz;
            for (const auto& p : force_model::profile_polyline(c.profile, kCellMm / 64)) rz.push_back({p.r_mm, p.z_mm});
            const kernels::ConvexToolSolid solid = kernels::convex_tool_solid(rz);
            const std::vector<kernels::PoseStep> steps = turning_path(c, g);
            force_model::PoseEngineSettings cl_settings;
            cl_settings.opencl = true;
            const auto box = [] { return kernels::make_tri_dexel_box({0, -12, -12}, {20, 12, 0}, kCellMm); };
            force_model::PoseEngine twin(box(), g, solid, params);
            force_model::PoseEngine cl(box(), g, solid, params, cl_settings);
            std::vector<kernels::StepResult> out_twin, out_cl, piece;
            double twin_s = 0, cl_s = 0;
            // In pieces, as the walk hands them over; the path ends (finish) once in the middle.
            for (std::size_t b = 0; b < steps.size(); b += 3000) {
                const std::vector<kernels::PoseStep> part(steps.begin() + std::ptrdiff_t(b),
                                                          steps.begin() + std::ptrdiff_t(std::min(steps.size(), b + 3000)));
                const auto t0 = std::chrono::steady_clock::now();
                twin.run(part, piece, 1.0);
                const auto t1 = std::chrono::steady_clock::now();
                out_twin.insert(out_twin.end(), piece.begin(), piece.end());
                cl.run(part, piece, 1.0);
                const auto t2 = std::chrono::steady_clock::now();
                out_cl.insert(out_cl.end(), piece.begin(), piece.end());
                twin_s += std::chrono::duration<double>(t1 - t0).count();
                cl_s += std::chrono::duration<double>(t2 - t1).count();
                if (b == 6000) {
                    twin.finish();
                    cl.finish();
                }
            }
            twin.finish();
            cl.finish();
            REQUIRE(out_cl.size() == out_twin.size());
            double peak_N = 0, peak_Nmm = 0, worst_N = 0, worst_Nmm = 0, worst_mm = 0;
            std::size_t cutting = 0, engaged_differ = 0;
            for (std::size_t i = 0; i < out_twin.size(); ++i) {
                const kernels::StepResult &a = out_twin[i], &b = out_cl[i];
                peak_N = std::max(peak_N, double(std::hypot(a.fx_N, a.fy_N, a.fz_N)));
                peak_Nmm = std::max({peak_Nmm, double(std::abs(a.torque_Nmm)), double(std::hypot(a.mx_Nmm, a.my_Nmm))});
                worst_N = std::max(worst_N, double(std::hypot(a.fx_N - b.fx_N, a.fy_N - b.fy_N, a.fz_N - b.fz_N)));
                worst_Nmm = std::max({worst_Nmm, double(std::abs(a.torque_Nmm - b.torque_Nmm)),
                                      double(std::abs(a.mx_Nmm - b.mx_Nmm)), double(std::abs(a.my_Nmm - b.my_Nmm))});
                if (a.engaged > 0 && b.engaged > 0)
                    worst_mm = std::max({worst_mm, double(std::abs(a.z_min_mm - b.z_min_mm)), double(std::abs(a.z_max_mm - b.z_max_mm)),
                                         double(std::abs(a.q_min_mm - b.q_min_mm)), double(std::abs(a.q_max_mm - b.q_max_mm)),
                                         double(std::abs(a.chip_mm - b.chip_mm))});
                cutting += a.engaged > 0;
                engaged_differ += std::abs(a.engaged - b.engaged) > 0.5f;
            }
            double ray_diff_mm = 0;
            std::size_t rays_differ = 0;
            for (int f = 0; f < 3; ++f) {
                const std::vector<float>&ra = twin.stock().family[f].rays, &rb = cl.stock().family[f].rays;
                REQUIRE(ra.size() == rb.size());
                for (std::size_t r = 0; r < ra.size(); ++r) {
                    if (ra[r] == rb[r]) continue;
                    ++rays_differ;
                    // An end that moved, not one slot empty in one and full in the other.
                    if (std::abs(ra[r]) < 1e29f && std::abs(rb[r]) < 1e29f)
                        ray_diff_mm = std::max(ray_diff_mm, double(std::abs(ra[r] - rb[r])));
                    else
                        ray_diff_mm = 1e30;
                }
            }
            INFO(fmt::format("{}: {} steps, {} cutting, peak {:.1f} N; OpenCL against the twins: force {:.3g} N, moments "
                             "{:.3g} N mm, extents {:.3g} mm, engaged counts differ on {} steps; removed {:.6f} vs {:.6f} "
                             "mm3; {} ray ends differ, by at most {:.3g} mm",
                             c.name, out_twin.size(), cutting, peak_N, worst_N, worst_Nmm, worst_mm, engaged_differ,
                             cl.removed_mm3(), twin.removed_mm3(), rays_differ, ray_diff_mm));
            testref::report_figure(fmt::format("tri-dexel OpenCL vs twins {}: {} steps, {} cutting; force {:.3g} of peak, "
                                               "removed {:.3g}, ray ends {:.3g} mm; twins {:.2f} s, OpenCL {:.2f} s",
                                               c.name, out_twin.size(), cutting, worst_N / peak_N,
                                               cl.removed_mm3() / twin.removed_mm3() - 1, ray_diff_mm, twin_s, cl_s));
            CHECK(cutting > 1000);
            CHECK(peak_N > 20);
            CHECK(twin.removed_mm3() > 50);
            CHECK(worst_N <= 1e-4 * peak_N);
            CHECK(worst_Nmm <= 1e-4 * peak_Nmm);
            CHECK(worst_mm <= 1e-5);
            CHECK(engaged_differ == 0);
            CHECK(cl.removed_mm3() == Approx(twin.removed_mm3()).epsilon(1e-9));
            CHECK(ray_diff_mm <= 1e-5);
            CHECK(cl.chords() == twin.chords());
            CHECK_THAT(cl.device(), Catch::Matchers::StartsWith("opencl"));
        }
    }
}

// The shank and holder check (body_rays) against its twin (tri_dexel_body_clearance) at 400 poses
// leaning 0 to 70 deg about a block with holes and a leaning groove, some clear, some in near
// misses, some in contact: the same verdicts, and the same clearances to 1e-9 mm.
TEST_CASE("tri-dexel OpenCL: the shank and holder check equals its twin", "[tri_dexel][opencl][holder]") {
    if (testref::devices_under_test().size() < 2) return;   // no OpenCL platform (it warns)
    kernels::TriDexel stock = kernels::make_tri_dexel_box({-20, -20, -20}, {20, 20, 0}, 0.2);
    const auto plunge = [&](double r_mm, const Vec& from, const Vec& to, const Mat& rot) {
        kernels::ToolChord c;
        c.from_mm = from;
        c.to_mm = to;
        c.rot = rot;
        kernels::sweep_tri_dexel(stock, kernels::convex_tool_solid({{0, 0}, {r_mm, 0}, {r_mm, 60}}), &c, 1);
    };
    plunge(6, {-8, -8, 5}, {-8, -8, -12}, lean(0, 0));
    plunge(3, {9, 4, 5}, {9, 4, -15}, lean(0, 0));
    plunge(4, {-15, 10, -3}, {15, 10, -6}, lean(0.5, 0.3));
    const force_model::Cutter cutter{force_model::corner_radius_profile(10, 5, 12), 2, 30, 30, 0, 0};
    const force_model::ToolGeometry g = force_model::build_tool_geometry(cutter, 0.2);
    std::vector<std::array<double, 2>> rz;
    for (const auto& p : force_model::profile_polyline(cutter.profile, 0.2 / 64)) rz.push_back({p.r_mm, p.z_mm});
    const kernels::ConvexToolSolid solid = kernels::convex_tool_solid(rz);
    kernels::EngageParams params;
    params.element_end = int(g.edges.size());
    auto twin = force_model::make_cpu_pose_backend(stock, g.edges, solid, params);
    auto cl = force_model::make_opencl_pose_backend(stock, g.edges, solid, params);
    kernels::ToolBody body;
    body.flute_length_mm = 12, body.stickout_mm = 18, body.holder_length_mm = 25;
    body.shank_radius_mm = 5, body.holder_radius_mm = 12;
    std::uint64_t seed = 12345;
    const auto uniform = [&seed](double lo, double hi) {
        seed = seed * 6364136223846793005ULL + 1442695040888963407ULL;
        return lo + (hi - lo) * double(seed >> 11) / double(1ULL << 53);
    };
    int contacts = 0, near_misses = 0, clear = 0;
    for (int k = 0; k < 400; ++k) {
        const Vec tip{uniform(-22, 22), uniform(-22, 22), uniform(-25, -2)};
        const Mat rot = lean(uniform(-1.2, 1.2), uniform(-0.6, 0.6));
        const double shell = k % 5 == 0 ? 0.0 : uniform(0.5, 6);
        const kernels::BodyClearance a = twin->body_clearance(tip, rot, body, shell);
        const kernels::BodyClearance b = cl->body_clearance(tip, rot, body, shell);
        INFO("pose " << k << " tip (" << tip[0] << ", " << tip[1] << ", " << tip[2] << ") shell " << shell);
        REQUIRE(a.contact == b.contact);
        if (std::isinf(a.clearance_mm))
            CHECK(std::isinf(b.clearance_mm));
        else
            CHECK(b.clearance_mm == Approx(a.clearance_mm).margin(1e-9));
        contacts += a.contact ? 1 : 0;
        near_misses += !a.contact && std::isfinite(a.clearance_mm) ? 1 : 0;
        clear += !a.contact && std::isinf(a.clearance_mm) ? 1 : 0;
    }
    // The poses cover all three verdicts.
    CHECK(contacts > 20);
    CHECK(near_misses > 10);
    CHECK(clear > 20);
}
