// Paths with corners: the force turns with the feed at a sharp corner and the second leg's block
// gets its own summary; and the seed's accident case, where a roughing run whose actual path
// rounded a corner leaves extra stock that overloads the finishing tool.
#include "force_model/reference.hpp"

#include <catch2/catch.hpp>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

using namespace cutload;
using namespace cutload::testref;

namespace {

constexpr double kRpm = 10000;

const force_model::BlockSummary* find_block(const force_model::Prediction& p, const std::string& name) {
    const auto it = std::find_if(p.blocks.begin(), p.blocks.end(), [&](const auto& b) { return b.block == name; });
    return it == p.blocks.end() ? nullptr : &*it;
}

const force_model::FlagHit* find_flag(const force_model::BlockSummary& b, const std::string& flag) {
    const auto it = std::find_if(b.flags.begin(), b.flags.end(), [&](const auto& f) { return f.flag == flag; });
    return it == b.flags.end() ? nullptr : &*it;
}

double resultant(const force_model::ForceSample& s) { return std::sqrt(s.fx_N * s.fx_N + s.fy_N * s.fy_N + s.fz_N * s.fz_N); }

double peak_resultant_in(const force_model::Prediction& p, const std::string& block) {
    const auto idx = std::find(p.block_names.begin(), p.block_names.end(), block) - p.block_names.begin();
    double peak = 0;
    for (const auto& s : p.samples)
        if (s.block == idx) peak = std::max(peak, resultant(s));
    return peak;
}

double peak_of_period(const Cut& cut, const Coefficients& k) {
    double peak = 0;
    for (int i = 0; i < 720; ++i)
        peak = std::max(peak, resultant_N(instantaneous_forces(cut, k, i * std::numbers::pi / 360.0, 200)));
    return peak;
}

std::string show(const Forces& f) { return fmt::format("({:.3f},{:.3f},{:.3f}) N", f.fx_N, f.fy_N, f.fz_N); }

}  // namespace

TEST_CASE("physics: at a sharp corner the force turns with the feed and the second leg has its own block",
          "[physics][corner]") {
    // Slot along +X (N10) to (10, 0), then along +Y (N20) to (10, 14), tool tip 2 mm below the top.
    const Cut cut = slot_cut(8, 2, 30, 2, 0.1);
    const Coefficients k = test_coefficients();
    Path path;
    path.start_mm = {-4.5, 0, 3};
    path.segments = {line_to({10, 0, 3}, "N10"), line_to({10, 14, 3}, "N20")};
    path.spindle_rpm = kRpm;
    path.feed_mm_min = cut.feed_per_tooth_mm * cut.flutes * kRpm;
    force_model::StockBox box;
    box.min_mm[0] = 0, box.min_mm[1] = -6, box.min_mm[2] = 0;
    box.max_mm[0] = 16, box.max_mm[1] = 20, box.max_mm[2] = 5;
    const double speed_mm_s = path.feed_mm_min / 60.0;
    const double t_corner_s = 14.5 / speed_mm_s;
    // Steady slotting: leg 1 with the centre in x 0.3..9.7; leg 2 once the whole front half is past
    // leg 1's slot (y >= R) until 0.3 mm before the end.
    const double leg1_t0 = 4.8 / speed_mm_s, leg1_t1 = 14.2 / speed_mm_s;
    const double leg2_t0 = t_corner_s + 4.3 / speed_mm_s, leg2_t1 = t_corner_s + 13.7 / speed_mm_s;
    const Forces slot = average_forces(cut, k);
    const double peak_ref_N = peak_of_period(cut, k);

    const motion_io::MotionModel motion = uniform_motion(path);
    for (force_model::Device device : devices_under_test()) {
        force_model::PredictOptions opt;
        opt.device = device;
        const force_model::Prediction p = force_model::predict(motion, flat_tool_spec(cut, k, box, 0.05), opt);
        const SteadyMean leg1 = steady_mean(p.samples, leg1_t0, leg1_t1, cut.flutes);
        const SteadyMean leg2 = steady_mean(p.samples, leg2_t0, leg2_t1, cut.flutes);
        const double err1 = relative_force_error(leg1.forces, slot);
        const double err2 = relative_force_error(leg2.forces, rotate_quarter_turns(slot, 1));
        const double turn_deg = (std::atan2(leg2.forces.fy_N, leg2.forces.fx_N) -
                                 std::atan2(leg1.forces.fy_N, leg1.forces.fx_N)) * 180 / std::numbers::pi;
        const force_model::BlockSummary* n20 = find_block(p, "N20");
        const std::string figures = fmt::format(
            "{} corner: leg 1 {} err {:.3f}%, leg 2 {} err {:.3f}%, turn {:.2f} deg; N20 summary t {:.4f}..{:.4f} s "
            "(corner {:.4f}), peak {:.2f} N (samples {:.2f}, reference {:.2f})",
            device_name(device), show(leg1.forces), 100 * err1, show(leg2.forces), 100 * err2,
            std::remainder(turn_deg, 360.0), n20 ? n20->t_start_s : -1, n20 ? n20->t_end_s : -1, t_corner_s,
            n20 ? n20->peak_force_N : -1, peak_resultant_in(p, "N20"), peak_ref_N);
        report_figure(figures);
        INFO(figures);
        REQUIRE(leg1.tooth_periods >= 10);
        REQUIRE(leg2.tooth_periods >= 10);
        CHECK(err1 < 0.02);
        CHECK(err2 < 0.02);
        CHECK(std::remainder(turn_deg, 360.0) == Approx(90).margin(1.0));
        REQUIRE(find_block(p, "N10") != nullptr);
        REQUIRE(n20 != nullptr);
        CHECK(n20->t_start_s == Approx(t_corner_s).margin(0.002));
        CHECK(n20->t_end_s == Approx(motion.t_s.back()).margin(0.002));
        CHECK(n20->peak_force_N == Approx(peak_resultant_in(p, "N20")).epsilon(1e-3));
        CHECK(n20->peak_force_N == Approx(peak_ref_N).epsilon(0.03));
        CHECK(n20->mean_force_N > 0.5 * n20->peak_force_N);
        CHECK(n20->removed_mm3 > 0);
    }
}

TEST_CASE("physics: stock left in a corner by a rounded roughing path overloads the finishing pass",
          "[physics][corner]") {
    // Roughing (same D 8 tool, slot 2 mm deep) along y = 10.5 towards a corner at x = 20, then out
    // along +Y; it leaves a 0.5 mm finishing allowance on the wall y = 6.5. As programmed the corner
    // is sharp; as the servo actually moved it, it was rounded with r = 8 mm, which leaves stock
    // between the arc's outer envelope (radius 12 about (12, 18.5)) and the wall. The finishing
    // pass (down milling, ae 0.5 mm) runs along y = 10: N10 before the rounded zone, N20 into it.
    const Cut finish = down_cut(8, 2, 30, 2, 0.1, 0.5);
    const Coefficients k = test_coefficients();
    force_model::StockBox box;
    box.min_mm[0] = 0, box.min_mm[1] = 0, box.min_mm[2] = 0;
    box.max_mm[0] = 26, box.max_mm[1] = 24, box.max_mm[2] = 5;
    const double z_tip = 3;

    Path programmed;
    programmed.start_mm = {-5, 10.5, z_tip};
    programmed.segments = {line_to({20, 10.5, z_tip}, "N100"), line_to({20, 29, z_tip}, "N110")};
    programmed.spindle_rpm = kRpm;
    programmed.feed_mm_min = 6000;
    Path actual = programmed;
    actual.segments = {line_to({12, 10.5, z_tip}, "N100"), arc_to({20, 18.5, z_tip}, 12, 18.5, true, "N100"),
                       line_to({20, 29, z_tip}, "N110")};

    Path finishing;
    finishing.start_mm = {-5, 10, z_tip};
    finishing.segments = {line_to({11, 10, z_tip}, "N10"), line_to({15.5, 10, z_tip}, "N20")};
    finishing.spindle_rpm = kRpm;
    finishing.feed_mm_min = finish.feed_per_tooth_mm * finish.flutes * kRpm;
    const double speed_mm_s = finishing.feed_mm_min / 60.0;

    force_model::RunSpec spec = flat_tool_spec(finish, k, box, 0.05);
    // The tool is rated for the finishing cut up to 1.5 mm radial depth: the peak of that cut.
    spec.limits.force_N = peak_of_period(down_cut(8, 2, 30, 2, 0.1, 1.5), k);
    const double planned_peak_N = peak_of_period(finish, k);

    for (force_model::Device device : devices_under_test()) {
        force_model::PredictOptions opt;
        opt.device = device;
        const force_model::Prediction rough_programmed = force_model::predict(uniform_motion(programmed), spec, opt);
        const force_model::Prediction rough_actual = force_model::predict(uniform_motion(actual), spec, opt);
        REQUIRE(rough_programmed.final_stock);
        REQUIRE(rough_actual.final_stock);
        const double v_programmed = force_model::stock_volume_mm3(*rough_programmed.final_stock);
        const double v_actual = force_model::stock_volume_mm3(*rough_actual.final_stock);

        const motion_io::MotionModel finishing_motion = uniform_motion(finishing);
        opt.base_stock = rough_programmed.final_stock.get();
        const force_model::Prediction clean = force_model::predict(finishing_motion, spec, opt);
        opt.base_stock = rough_actual.final_stock.get();
        const force_model::Prediction leftover = force_model::predict(finishing_motion, spec, opt);

        // Far from the corner both stocks are the same: same steady forces.
        const double t0 = 5.3 / speed_mm_s, t1 = 13.0 / speed_mm_s;
        const SteadyMean clean_steady = steady_mean(clean.samples, t0, t1, finish.flutes);
        const SteadyMean leftover_steady = steady_mean(leftover.samples, t0, t1, finish.flutes);
        const double steady_diff = relative_force_error(leftover_steady.forces, clean_steady.forces);
        const double clean_peak = peak_resultant_in(clean, "N20");
        const double leftover_peak = peak_resultant_in(leftover, "N20");
        const std::string figures = fmt::format(
            "{} roughing then finishing: stock after roughing {:.1f} (programmed) vs {:.1f} mm3 (actual); "
            "finishing N10 steady {} vs {} diff {:.3f}%; N20 peak {:.1f} N clean vs {:.1f} N leftover; planned "
            "peak {:.1f} N, limit {:.1f} N",
            device_name(device), v_programmed, v_actual, show(clean_steady.forces), show(leftover_steady.forces),
            100 * steady_diff, clean_peak, leftover_peak, planned_peak_N, spec.limits.force_N);
        report_figure(figures);
        INFO(figures);
        CHECK(v_actual > v_programmed + 5.0);
        REQUIRE(clean_steady.tooth_periods >= 10);
        CHECK(steady_diff < 0.01);
        CHECK(clean_peak == Approx(planned_peak_N).epsilon(0.05));
        CHECK(leftover_peak > 1.3 * clean_peak);

        for (const force_model::Prediction* run : {&clean, &leftover}) {
            for (const char* name : {"N10", "N20"}) REQUIRE(find_block(*run, name) != nullptr);
            CHECK(find_flag(*find_block(*run, "N10"), "force_limit") == nullptr);
        }
        CHECK(find_flag(*find_block(clean, "N20"), "force_limit") == nullptr);
        const force_model::FlagHit* hit = find_flag(*find_block(leftover, "N20"), "force_limit");
        REQUIRE(hit != nullptr);
        CHECK(hit->value > spec.limits.force_N);
        CHECK(hit->t_s >= 16.0 / speed_mm_s);
    }
}
