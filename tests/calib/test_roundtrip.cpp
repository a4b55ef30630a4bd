// Round trip: forces predicted with known coefficients -> dynamometer files (inverse axis matrix,
// force on the workpiece, 10 kHz, runout, noise, zero offset, time shift) -> read, mapped, aligned
// and calibrated again. The coefficients must come back within 2 % and the shift within one sample.
#include "calib/dyno_fixture.hpp"
#include "force_model/calibrate.hpp"
#include "force_model/compare.hpp"

#include <catch2/catch.hpp>
#include <fmt/format.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>

using namespace cutload;
using namespace cutload::force_model;
using namespace cutload::calibtest;

namespace {

constexpr double kRpm = 10000;

void report(const std::string& line) {
    static const bool verbose = std::getenv("CUTLOAD_CALIB_VERBOSE") != nullptr;
    if (verbose) std::printf("CALIB %s\n", line.c_str());
}

struct Case {
    Side side;
    double feed_per_tooth_mm, radial_mm;
};

Immersion immersion_of(Side s) { return s == Side::Slot ? Immersion::Slot : s == Side::Up ? Immersion::Up : Immersion::Down; }

CutTest cut_test(const Case& c, double axial_mm) {
    CutTest t;
    t.spindle_rpm = kRpm;
    t.feed_mm_min = c.feed_per_tooth_mm * test_tool().flutes * kRpm;
    t.axial_mm = axial_mm;
    t.radial_mm = c.radial_mm;
    t.mode = immersion_of(c.side);
    return t;
}

std::filesystem::path scratch_dir(const char* name) {
    const auto dir = std::filesystem::temp_directory_path() / name;
    std::filesystem::create_directories(dir);
    return dir;
}

Prediction predict_cpu(const StraightCut& cut) {
    PredictOptions o;
    o.device = Device::Cpu;
    return predict(cut.motion, cut.spec, o);
}

void check_material(const Material& got, const Material& want, double tolerance) {
    const auto g = coefficients_of(got), w = coefficients_of(want);
    for (std::size_t k = 0; k < 6; ++k) {
        INFO(kCoefficientKeys[k] << ": identified " << g[k] << ", true " << w[k]);
        CHECK(std::abs(g[k] / w[k] - 1) < tolerance);
    }
}

}  // namespace

TEST_CASE("round trip through dynamometer files re-identifies the six coefficients within 2 %",
          "[calib][roundtrip]") {
    const double axial_mm = 2;
    const std::vector<Case> cases = {{Side::Slot, 0.04, 0}, {Side::Slot, 0.08, 0}, {Side::Slot, 0.12, 0},
                                     {Side::Slot, 0.16, 0}, {Side::Down, 0.06, 2}, {Side::Down, 0.14, 2},
                                     {Side::Up, 0.1, 3}};
    const auto dir = scratch_dir("cutload_calib_roundtrip");
    std::vector<Regressors> regs;
    std::vector<std::array<double, 3>> means;
    DynoOptions dyno;
    for (std::size_t i = 0; i < cases.size(); ++i) {
        const Case& c = cases[i];
        const StraightCut cut = straight_cut(c.feed_per_tooth_mm, axial_mm, c.side, c.radial_mm);
        const Prediction truth = predict_cpu(cut);
        const std::string file = (dir / fmt::format("test{}.csv", i)).string();
        dyno.seed = 100 + static_cast<unsigned>(i);
        write_dyno_file(truth, file, dyno);

        Measurement m = read_measurement(file);
        map_to_tool_machine_axes(m, kSeedAxes);
        const SteadyForce steady = steady_mean_force(m, kRpm);
        const CutTest test = cut_test(c, axial_mm);
        regs.push_back(engine_regressors(test_tool(), test));
        means.push_back(to_feed_frame(steady.mean_N, test.feed_direction_deg));
        report(fmt::format("{} c={} ae={}: steady {:.3f}-{:.3f} s ({} rev), mean ({:.2f}, {:.2f}, {:.2f}) N, zero "
                           "({:.2f}, {:.2f}, {:.2f}) N",
                           immersion_name(test.mode), c.feed_per_tooth_mm, c.radial_mm, steady.t_start_s,
                           steady.t_end_s, steady.revolutions, steady.mean_N[0], steady.mean_N[1], steady.mean_N[2],
                           steady.zero_N[0], steady.zero_N[1], steady.zero_N[2]));
        REQUIRE(steady.revolutions >= 10);
        CHECK(steady.zeroed);
        // The zero offset is found in tool / machine axes: -A * zero_dyn.
        CHECK(steady.zero_N[0] == Approx(-(-dyno.zero_N[1])).margin(0.3));
        CHECK(steady.zero_N[1] == Approx(-(-dyno.zero_N[0])).margin(0.3));
    }
    const CalibrationFit fit = fit_mean_forces(regs, means, "identified");
    const auto k = coefficients_of(fit.material);
    report(fmt::format("identified Ktc {:.2f} Krc {:.2f} Kac {:.2f} Kte {:.3f} Kre {:.3f} Kae {:.3f}; rms residual "
                       "{:.3f} N ({:.3f} %), condition {:.1f}",
                       k[0], k[1], k[2], k[3], k[4], k[5], fit.rms_residual_N, 100 * fit.relative_rms_residual,
                       fit.condition_number));
    check_material(fit.material, true_material(), 0.02);
    CHECK(fit.equations == 3 * cases.size());
    CHECK(fit.relative_rms_residual < 0.01);
    CHECK(fit.condition_number < 100);
    std::filesystem::remove_all(dir);
}

TEST_CASE("the time shift of a dynamometer file is found within one sample", "[calib][roundtrip][align]") {
    const auto dir = scratch_dir("cutload_calib_shift");
    const StraightCut cut = straight_cut(0.08, 2, Side::Down, 3);
    const Prediction truth = predict_cpu(cut);
    for (double delay_s : {0.05123, 0.2171}) {
        DynoOptions dyno;
        dyno.delay_s = delay_s;
        const std::string file = (dir / "shift.csv").string();
        write_dyno_file(truth, file, dyno);
        Measurement m = read_measurement(file);
        map_to_tool_machine_axes(m, kSeedAxes);
        CompareOptions opt;
        const Comparison c = compare(predicted_trace(truth), m, opt);
        report(fmt::format("delay {} s: offset {:.6f} s (error {:.2f} samples), score {:.4f}, resultant nrmse "
                           "{:.4f}, correlation {:.4f}",
                           delay_s, c.offset_s, (c.offset_s + delay_s) * m.rate_Hz, c.alignment_score,
                           c.overall.axes[3].nrmse, c.overall.axes[3].correlation));
        CHECK(std::abs(c.offset_s + delay_s) < 1.0 / m.rate_Hz);
        CHECK(c.alignment_score > 0.9);
        // The zero offset, from where the prediction is in air, in tool / machine axes: -A zero_dyn.
        REQUIRE(c.zero_removed);
        CHECK(c.zero_N[0] == Approx(dyno.zero_N[1]).margin(0.3));
        CHECK(c.zero_N[1] == Approx(dyno.zero_N[0]).margin(0.3));
        CHECK(c.zero_N[2] == Approx(-dyno.zero_N[2]).margin(0.3));
        // Noise (2 % of peak) and runout (4 %) are all that differ once aligned and filtered.
        CHECK(c.overall.axes[3].correlation > 0.98);
        CHECK(c.overall.axes[3].nrmse < 0.05);
    }
    std::filesystem::remove_all(dir);
}

TEST_CASE("engine and closed-form regressors agree for a flat end mill", "[calib][regressors]") {
    for (const Case& c : {Case{Side::Slot, 0.1, 0}, Case{Side::Down, 0.1, 2}, Case{Side::Up, 0.05, 5}}) {
        const CutTest t = cut_test(c, 3);
        const Regressors e = engine_regressors(test_tool(), t);
        const Regressors f = closed_form_regressors(test_tool(), t);
        for (std::size_t k = 0; k < 6; ++k) {
            double diff = 0, norm = 0;
            for (std::size_t ax = 0; ax < 3; ++ax) {
                diff += std::pow(e[ax][k] - f[ax][k], 2);
                norm += std::pow(f[ax][k], 2);
            }
            INFO(immersion_name(t.mode) << " " << kCoefficientKeys[k] << ": engine (" << e[0][k] << ", " << e[1][k]
                                        << ", " << e[2][k] << ") closed form (" << f[0][k] << ", " << f[1][k] << ", "
                                        << f[2][k] << ")");
            CHECK(std::sqrt(diff / norm) < 0.02);
        }
    }
    ToolSpec ball = test_tool();
    ball.shape = ToolShape::Ball;
    ball.corner_radius_mm = 4;
    CHECK_THROWS_WITH(closed_form_regressors(ball, cut_test({Side::Slot, 0.1, 0}, 2)),
                      Catch::Contains("flat end mills only"));
}

TEST_CASE("slot tests alone determine all six coefficients, one feed does not", "[calib][regressors]") {
    // Closed-form regressors and exact mean forces: the classic slot regression.
    const Material truth = true_material();
    const auto k = coefficients_of(truth);
    auto means_of = [&](const Regressors& r) {
        std::array<double, 3> f{};
        for (std::size_t ax = 0; ax < 3; ++ax)
            for (std::size_t j = 0; j < 6; ++j) f[ax] += r[ax][j] * k[j];
        return f;
    };
    std::vector<Regressors> regs;
    std::vector<std::array<double, 3>> means;
    for (double c : {0.05, 0.1, 0.15, 0.2}) {
        regs.push_back(closed_form_regressors(test_tool(), cut_test({Side::Slot, c, 0}, 2)));
        means.push_back(means_of(regs.back()));
    }
    const CalibrationFit fit = fit_mean_forces(regs, means, "slot");
    check_material(fit.material, truth, 1e-9);
    CHECK(fit.rms_residual_N < 1e-9);
    CHECK_THROWS_WITH(fit_mean_forces({regs[0], regs[0]}, {means[0], means[0]}, "one feed"),
                      Catch::Contains("cannot separate"));
    CHECK_THROWS_WITH(fit_mean_forces({regs[0]}, {means[0]}, "one test"), Catch::Contains("3 equations"));
}

TEST_CASE("measured runs along their own paths calibrate through the engine's regressors",
          "[calib][roundtrip][runs]") {
    const auto dir = scratch_dir("cutload_calib_runs");
    const std::vector<Case> cases = {{Side::Slot, 0.05, 0}, {Side::Slot, 0.15, 0}, {Side::Down, 0.1, 2}};
    std::vector<StraightCut> cuts;
    std::vector<Measurement> measured;
    for (std::size_t i = 0; i < cases.size(); ++i) {
        cuts.push_back(straight_cut(cases[i].feed_per_tooth_mm, 2, cases[i].side, cases[i].radial_mm));
        DynoOptions dyno;
        dyno.seed = 200 + static_cast<unsigned>(i);
        const std::string file = (dir / fmt::format("run{}.csv", i)).string();
        write_dyno_file(predict_cpu(cuts.back()), file, dyno);
        measured.push_back(read_measurement(file));
        map_to_tool_machine_axes(measured.back(), kSeedAxes);
    }
    std::vector<MeasuredRun> runs;
    for (std::size_t i = 0; i < cases.size(); ++i) {
        MeasuredRun r;
        r.motion = &cuts[i].motion;
        r.spec = cuts[i].spec;
        r.spec.material = {"guess", 500, 100, 100, 10, 10, 1};   // only used to align
        r.measured = &measured[i];
        runs.push_back(r);
    }
    const CalibrationFit fit = calibrate_from_runs(runs, {}, "runs");
    const auto k = coefficients_of(fit.material);
    report(fmt::format("runs: Ktc {:.2f} Krc {:.2f} Kac {:.2f} Kte {:.3f} Kre {:.3f} Kae {:.3f}; rms residual {:.3f} N, "
                       "condition {:.1f}, {} equations",
                       k[0], k[1], k[2], k[3], k[4], k[5], fit.rms_residual_N, fit.condition_number, fit.equations));
    check_material(fit.material, true_material(), 0.02);
    std::filesystem::remove_all(dir);
}
