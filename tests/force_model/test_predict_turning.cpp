// force_model::predict_turning (docs/five_axis.md section 3.4): the walk around the pose engine.
// Two one-way passes through the same block at cutting depth, the tool leaving it sideways and
// going round it through the air to enter again beside the first (the grooves, 4.2 mm each side
// of y = 0 and y = 10, stay apart): the second pass must cut as the first did. A removal swept
// straight from where the tool left the block (x 45, y 0) to where it could reach it again
// (x -8, y 40) would cut a diagonal through the second pass's material (it did, before the pose
// engine ended its path on leaving). The rows
// handed out in pieces must be the rows, and what it cannot take is refused.
#include "force_model/force_model.hpp"
#include "force_model/motion_fixtures.hpp"
#include "force_model/reference.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

using namespace cutload;

namespace {

// A D10 ball end mill leaning 20 deg toward +X, 2 mm into the top of the block x 0..40,
// y -15..35, z -20..0; 0.2 mm cells and elements (the two passes are compared with each other).
constexpr const char* kSpec = R"json({
  "tool": {"shape": "ball", "diameter_mm": 10, "flutes": 2, "helix_deg": 30, "corner_radius_mm": 5,
           "flute_length_mm": 20, "stickout_mm": 30},
  "material": {"name": "test", "Ktc_N_mm2": 700, "Krc_N_mm2": 210, "Kac_N_mm2": 120,
               "Kte_N_mm": 20, "Kre_N_mm": 28, "Kae_N_mm": 2},
  "stock": {"box_mm": {"min": [0, -15, -20], "max": [40, 35, 0]}},
  "resolution": {"angle_step_deg": 2, "axial_step_mm": 0.2, "grid_mm": 0.2}
})json";

constexpr double kFeed_mm_min = 2000;

testref::Path two_passes() {
    testref::Path p;
    p.start_mm = {-8, 0, -2};
    p.segments = {testref::line_to({48, 0, -2}, "N10"), testref::line_to({48, 45, -2}, "N20"),
                  testref::line_to({-8, 45, -2}, "N30"), testref::line_to({-8, 10, -2}, "N40"),
                  testref::line_to({48, 10, -2}, "N50")};
    p.feed_mm_min = kFeed_mm_min;
    p.spindle_rpm = 10000;
    return p;
}

force_model::ToolPoses leaning_poses(std::size_t n) {
    const double l = 20 * std::numbers::pi / 180;
    force_model::Rotation3 r;
    // Columns: tool x = (cos l, 0, -sin l), y = (0, 1, 0), z = (sin l, 0, cos l).
    r.m = {std::cos(l), 0, std::sin(l), 0, 1, 0, -std::sin(l), 0, std::cos(l)};
    force_model::ToolPoses poses;
    poses.tool_to_stock.assign(n, r);
    poses.omega_tool_rad_s.assign(n, {0, 0, 0});
    return poses;
}

std::array<double, 3> mean_force(const std::vector<force_model::ForceSample>& rows, double t0, double t1) {
    std::array<double, 3> sum{};
    std::size_t n = 0;
    for (const auto& r : rows)
        if (r.t_s >= t0 && r.t_s <= t1) {
            sum[0] += r.fx_N, sum[1] += r.fy_N, sum[2] += r.fz_N;
            ++n;
        }
    REQUIRE(n > 1000);
    return {sum[0] / n, sum[1] / n, sum[2] / n};
}

}  // namespace

TEST_CASE("predict_turning: a second pass after an air move cuts as the first, rows in pieces are the rows",
          "[tri_dexel][turning]") {
    const testref::Path path = two_passes();
    const motion_io::MotionModel motion = testref::uniform_motion(path);
    const force_model::ToolPoses poses = leaning_poses(motion.size());
    const force_model::RunSpec spec = force_model::parse_run_spec_text(kSpec, "turning.json");
    force_model::PredictOptions opt;
    opt.device = force_model::Device::Cpu;
    const force_model::Prediction p = force_model::predict_turning(motion, poses, spec, opt);

    // Pass windows: the tool 20 to 38 mm into the block, on each pass (the diagonal would cross the
    // second at x 26 to 37).
    const double v = kFeed_mm_min / 60;
    const double pass2_start_s = (56 + 45 + 56 + 35) / v;
    const auto f1 = mean_force(p.samples, 28 / v, 46 / v);
    const auto f2 = mean_force(p.samples, pass2_start_s + 28 / v, pass2_start_s + 46 / v);
    const double scale = std::hypot(f1[0], f1[1], f1[2]);
    INFO("pass 1 (" << f1[0] << ", " << f1[1] << ", " << f1[2] << ") N, pass 2 (" << f2[0] << ", " << f2[1] << ", "
                    << f2[2] << ") N");
    CHECK(scale > 50);
    for (int c = 0; c < 3; ++c) CHECK(std::abs(f1[c] - f2[c]) < 0.01 * scale);
    // Both grooves are removed whole and booked on rows: the ball's circular segment, 40 mm long
    // each, give or take the ends' shapes (its lowest point lies R (1 - cos 20 deg) below the tip,
    // 2.30 mm deep; the shank stays 0.99 mm above the face). Nothing in the air moves cut.
    double removed = 0;
    for (const auto& r : p.samples) removed += r.removed_mm3;
    const double h = 2 + 5 * (1 - std::cos(20 * std::numbers::pi / 180));
    const double groove = 25 * std::acos((5 - h) / 5) - (5 - h) * std::sqrt(10 * h - h * h);
    CHECK(removed > 2 * groove * 40 * 0.98);
    CHECK(removed < 2 * groove * 48);
    for (const auto& b : p.blocks)
        if (b.block == "N20" || b.block == "N30" || b.block == "N40") CHECK(b.peak_force_N < 1e-6);
    REQUIRE(p.final_stock);

    // The same rows when they are handed out in pieces as they become final.
    std::vector<force_model::ForceSample> streamed;
    std::size_t pieces = 0;
    opt.rows_out = [&](std::span<const force_model::ForceSample> rows) {
        streamed.insert(streamed.end(), rows.begin(), rows.end());
        ++pieces;
    };
    const force_model::Prediction q = force_model::predict_turning(motion, poses, spec, opt);
    CHECK(q.samples.empty());
    CHECK(pieces > 2);
    REQUIRE(streamed.size() == p.samples.size());
    for (std::size_t i = 0; i < streamed.size(); i += 97) {
        CHECK(streamed[i].t_s == p.samples[i].t_s);
        CHECK(streamed[i].fx_N == p.samples[i].fx_N);
        CHECK(streamed[i].removed_mm3 == p.samples[i].removed_mm3);
    }
    REQUIRE(q.blocks.size() == p.blocks.size());
    for (std::size_t b = 0; b < q.blocks.size(); ++b) CHECK(q.blocks[b].peak_force_N == p.blocks[b].peak_force_N);
}

TEST_CASE("predict_turning: poses that do not match the motion are refused", "[tri_dexel][turning][errors]") {
    const motion_io::MotionModel motion = testref::uniform_motion(two_passes());
    const force_model::RunSpec spec = force_model::parse_run_spec_text(kSpec, "turning.json");
    force_model::PredictOptions opt;
    opt.device = force_model::Device::Cpu;
    CHECK_THROWS_AS(force_model::predict_turning(motion, leaning_poses(motion.size() - 1), spec, opt), std::invalid_argument);
}

// A tool table: T1 (the ball D10) cuts the first pass, T2 (a ball D8) the second, which overlaps
// the first's groove. The first pass's rows equal T1's run alone; the second's means agree with T2
// from the stock T1 left (a base stock: its X and Y rays to the cell, so within 1 %).
TEST_CASE("predict_turning: a tool change hands the stock to the next cutter", "[tri_dexel][turning][tools]") {
    std::string table(kSpec);
    table.replace(table.find("\"material\""), 0,
                  R"json("tools": [{"number": 1, "shape": "ball", "diameter_mm": 10, "flutes": 2, "helix_deg": 30, "flute_length_mm": 20, "stickout_mm": 30},
                                   {"number": 2, "shape": "ball", "diameter_mm": 8, "flutes": 3, "helix_deg": 30, "flute_length_mm": 20, "stickout_mm": 30}],
  )json");
    const force_model::RunSpec spec = force_model::parse_run_spec_text(table, "tools.json");
    testref::Path both;
    both.start_mm = {-8, 0, -2};
    both.segments = {testref::line_to({48, 0, -2}, "N10"), testref::line_to({48, 45, -2}, "N20"),
                     testref::line_to({-8, 45, -2}, "N30"), testref::line_to({-8, 5, -2}, "N40"),
                     testref::line_to({48, 5, -2}, "N50")};
    both.feed_mm_min = kFeed_mm_min;
    both.spindle_rpm = 10000;
    motion_io::MotionModel m = testref::uniform_motion(both);
    const double v = kFeed_mm_min / 60;
    const double change_s = (56 + 45) / v, b_start_s = (56 + 45 + 56 + 40) / v;
    m.tool.resize(m.size());
    for (std::size_t i = 0; i < m.size(); ++i) m.tool[i] = m.t_s[i] < change_s ? 1 : 2;
    testref::Path only_a = both;
    only_a.segments.resize(1);
    motion_io::MotionModel m_a = testref::uniform_motion(only_a);
    m_a.tool.assign(m_a.size(), 1);
    testref::Path only_b;
    only_b.start_mm = {-8, 5, -2};
    only_b.segments = {testref::line_to({48, 5, -2}, "N50")};
    only_b.feed_mm_min = kFeed_mm_min;
    only_b.spindle_rpm = 10000;
    motion_io::MotionModel m_b = testref::uniform_motion(only_b);
    m_b.tool.assign(m_b.size(), 2);
    for (const force_model::Device d : testref::devices_under_test()) {
        INFO(testref::device_name(d));
        force_model::PredictOptions opt;
        opt.device = d;
        const force_model::Prediction one = force_model::predict_turning(m, leaning_poses(m.size()), spec, opt);
        opt.keep_final_stock = true;
        const force_model::Prediction a = force_model::predict_turning(m_a, leaning_poses(m_a.size()), spec, opt);
        REQUIRE(a.final_stock);
        opt.keep_final_stock = false;
        opt.base_stock = a.final_stock.get();
        const force_model::Prediction b = force_model::predict_turning(m_b, leaning_poses(m_b.size()), spec, opt);

        // Pass A: the same rows, bit for bit, and T1 on them.
        std::size_t a_rows = 0;
        for (const auto& r : a.samples)
            if (r.t_s < 56 / v) ++a_rows;
        REQUIRE(a_rows > 1000);
        for (std::size_t i = 0; i < a_rows; ++i) {
            REQUIRE(one.samples[i].t_s == a.samples[i].t_s);
            CHECK(one.samples[i].fx_N == a.samples[i].fx_N);
            CHECK(one.samples[i].fz_N == a.samples[i].fz_N);
            CHECK(one.samples[i].tool == 1);
        }
        // Pass B: T2 on its rows, and the mean of the stock T1 left.
        const auto f_one = mean_force(one.samples, b_start_s + 28 / v, b_start_s + 46 / v);
        const auto f_b = mean_force(b.samples, 28 / v, 46 / v);
        const double scale = std::hypot(f_one[0], f_one[1], f_one[2]);
        INFO("pass B in one run (" << f_one[0] << ", " << f_one[1] << ", " << f_one[2] << ") N, from T1's stock (" << f_b[0]
                                   << ", " << f_b[1] << ", " << f_b[2] << ") N");
        CHECK(scale > 20);
        for (int c = 0; c < 3; ++c) CHECK(std::abs(f_one[c] - f_b[c]) < 0.01 * scale);
        for (const auto& r : one.samples)
            if (r.t_s > b_start_s) CHECK(r.tool == 2);
    }
}

TEST_CASE("predict_turning on the OpenCL device gives the scalar twins' rows, blocks and final stock", "[tri_dexel][turning][opencl]") {
    const std::vector<force_model::Device> devices = testref::devices_under_test();
    if (devices.size() < 2) return;   // no OpenCL platform (it warns)
    const testref::Path path = two_passes();
    const motion_io::MotionModel motion = testref::uniform_motion(path);
    const force_model::ToolPoses poses = leaning_poses(motion.size());
    const force_model::RunSpec spec = force_model::parse_run_spec_text(kSpec, "turning.json");
    force_model::PredictOptions opt;
    opt.keep_final_stock = true;
    opt.device = force_model::Device::Cpu;
    const force_model::Prediction twin = force_model::predict_turning(motion, poses, spec, opt);
    opt.device = force_model::Device::OpenCL;
    const force_model::Prediction cl = force_model::predict_turning(motion, poses, spec, opt);
    INFO("twins: " << twin.stats.device << "; OpenCL: " << cl.stats.device);
    CHECK_THAT(cl.stats.device, Catch::Matchers::StartsWith("opencl"));
    CHECK_THAT(twin.stats.device, Catch::Matchers::StartsWith("cpu"));
    REQUIRE(cl.samples.size() == twin.samples.size());
    double peak_N = 0, worst_N = 0, removed_twin = 0, removed_cl = 0;
    for (std::size_t i = 0; i < twin.samples.size(); ++i) {
        const auto &a = twin.samples[i], &b = cl.samples[i];
        peak_N = std::max(peak_N, double(std::hypot(a.fx_N, a.fy_N, a.fz_N)));
        worst_N = std::max(worst_N, double(std::hypot(a.fx_N - b.fx_N, a.fy_N - b.fy_N, a.fz_N - b.fz_N)));
        removed_twin += a.removed_mm3;
        removed_cl += b.removed_mm3;
    }
    INFO("peak " << peak_N << " N, largest difference " << worst_N << " N; removed " << removed_cl << " vs " << removed_twin << " mm3");
    CHECK(peak_N > 50);
    // The issue asks for 0.5 %; the kernels are double precision like the twins.
    CHECK(worst_N <= 1e-4 * peak_N);
    CHECK(removed_cl == Approx(removed_twin).epsilon(1e-9));
    CHECK(cl.stats.cutting_steps == twin.stats.cutting_steps);
    REQUIRE(cl.blocks.size() == twin.blocks.size());
    for (std::size_t b = 0; b < cl.blocks.size(); ++b)
        CHECK(cl.blocks[b].peak_force_N == Approx(twin.blocks[b].peak_force_N).epsilon(1e-4).margin(1e-6));
    REQUIRE(cl.final_stock);
    REQUIRE(twin.final_stock);
    CHECK(force_model::stock_volume_mm3(*cl.final_stock) == Approx(force_model::stock_volume_mm3(*twin.final_stock)).epsilon(1e-9));
}

// A base stock (a Z-map, as a three-axis run or an earlier turning run leaves it) as the start of
// the multi-direction stock: pass A, then pass B from A's final stock, against A and B in one run.
// B overlaps A's groove by 2.4 mm, so it cuts into the groove's wall, which the X and Y rays of the
// converted stock hold to the cell (the Z rays exactly).
TEST_CASE("predict_turning from a base stock cuts as the same passes in one run", "[tri_dexel][turning][base_stock]") {
    const auto path_of = [](const testref::Vec3& start, std::vector<testref::PathSegment> legs) {
        testref::Path p;
        p.start_mm = start;
        p.segments = std::move(legs);
        p.feed_mm_min = kFeed_mm_min;
        p.spindle_rpm = 10000;
        return p;
    };
    const testref::Path both = path_of({-8, 0, -2}, {testref::line_to({48, 0, -2}, "N10"), testref::line_to({48, 45, -2}, "N20"),
                                                     testref::line_to({-8, 45, -2}, "N30"), testref::line_to({-8, 6, -2}, "N40"),
                                                     testref::line_to({48, 6, -2}, "N50")});
    const testref::Path a = path_of({-8, 0, -2}, {testref::line_to({48, 0, -2}, "N10")});
    const testref::Path b = path_of({-8, 6, -2}, {testref::line_to({48, 6, -2}, "N50")});
    const force_model::RunSpec spec = force_model::parse_run_spec_text(kSpec, "turning.json");
    for (const force_model::Device d : testref::devices_under_test()) {
        INFO(testref::device_name(d));
        force_model::PredictOptions opt;
        opt.device = d;
        const auto m_both = testref::uniform_motion(both), m_a = testref::uniform_motion(a), m_b = testref::uniform_motion(b);
        const force_model::Prediction one = force_model::predict_turning(m_both, leaning_poses(m_both.size()), spec, opt);
        opt.keep_final_stock = true;
        const force_model::Prediction first = force_model::predict_turning(m_a, leaning_poses(m_a.size()), spec, opt);
        REQUIRE(first.final_stock);
        opt.keep_final_stock = false;
        opt.base_stock = first.final_stock.get();
        const force_model::Prediction second = force_model::predict_turning(m_b, leaning_poses(m_b.size()), spec, opt);

        const double v = kFeed_mm_min / 60;
        const double b_in_one_s = (56 + 45 + 56 + 39) / v;
        const auto f_one = mean_force(one.samples, b_in_one_s + 28 / v, b_in_one_s + 46 / v);
        const auto f_two = mean_force(second.samples, 28 / v, 46 / v);
        // Without the base stock pass B would cut a full groove: the wall it meets is A's.
        opt.base_stock = nullptr;
        const force_model::Prediction fresh = force_model::predict_turning(m_b, leaning_poses(m_b.size()), spec, opt);
        const auto f_fresh = mean_force(fresh.samples, 28 / v, 46 / v);
        const double scale = std::hypot(f_one[0], f_one[1], f_one[2]);
        INFO("one run (" << f_one[0] << ", " << f_one[1] << ", " << f_one[2] << ") N, from the base (" << f_two[0] << ", "
                         << f_two[1] << ", " << f_two[2] << ") N, fresh (" << f_fresh[0] << ", " << f_fresh[1] << ", "
                         << f_fresh[2] << ") N");
        CHECK(scale > 30);
        for (int c = 0; c < 3; ++c) CHECK(std::abs(f_one[c] - f_two[c]) < 0.01 * scale);
        CHECK(std::hypot(f_one[0] - f_fresh[0], f_one[1] - f_fresh[1], f_one[2] - f_fresh[2]) > 0.1 * scale);
        double removed_one = 0, removed_two = 0;
        for (const auto& r : one.samples)
            if (r.t_s >= b_in_one_s) removed_one += r.removed_mm3;
        for (const auto& r : second.samples) removed_two += r.removed_mm3;
        INFO("pass B removed " << removed_one << " mm3 in one run, " << removed_two << " from the base");
        CHECK(removed_two == Approx(removed_one).epsilon(0.01));
    }
}
