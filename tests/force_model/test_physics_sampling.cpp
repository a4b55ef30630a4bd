// The same cut logged in the seed's irregular sampling pattern (6 ms client cycle, 4 ms CNC
// position grid, per-channel time stamps, repeats and misses) and as a regular 1 ms log: after
// motion_io::ingest repairs the irregular one, the mean forces agree within 1 %.
#include "force_model/reference.hpp"

#include <catch2/catch.hpp>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>
#include <unistd.h>

using namespace cutload;
using namespace cutload::testref;

namespace {

// First time at which the tool centre (stock coordinates) passes x_mm moving along +X.
double time_at_x(const motion_io::MotionModel& m, double offset_x_mm, double x_mm) {
    for (std::size_t i = 0; i + 1 < m.size(); ++i) {
        const double a = m.x_mm[i] + offset_x_mm, b = m.x_mm[i + 1] + offset_x_mm;
        if (a < x_mm && b >= x_mm) return m.t_s[i] + (x_mm - a) / (b - a) * (m.t_s[i + 1] - m.t_s[i]);
    }
    FAIL("the motion never reaches x = " << x_mm);
    return 0;
}

// Spread of the per-tooth-period peak resultant over the window: (max - min) / mean. At constant
// feed every tooth period is the same cut, so a spread is a sampling artefact in the motion - or
// the engine's own discretisation: one 0.1 mm axial element entering a 3 mm cut a row earlier or
// later moves a peak by about 4 %, so spreads up to kPeakSpreadAllowed are not blamed on motion.
constexpr double kPeakSpreadAllowed = 0.10;
double tooth_peak_spread(const std::vector<force_model::ForceSample>& samples, double t0_s, double t1_s, int flutes) {
    const double period_deg = 360.0 / flutes;
    std::vector<double> peaks;
    double a0 = 0;
    for (const auto& s : samples) {
        if (s.t_s < t0_s || s.t_s > t1_s) continue;
        if (peaks.empty()) a0 = s.spindle_angle_deg;
        const auto period = static_cast<std::size_t>((s.spindle_angle_deg - a0) / period_deg);
        if (period >= peaks.size()) peaks.resize(period + 1, 0.0);
        peaks[period] = std::max<double>(peaks[period], std::hypot(s.fx_N, s.fy_N, s.fz_N));
    }
    if (peaks.size() < 3) return 1e9;
    peaks.pop_back();   // the last period is cut short by the window
    const auto [lo, hi] = std::minmax_element(peaks.begin(), peaks.end());
    double mean = 0;
    for (double p : peaks) mean += p / static_cast<double>(peaks.size());
    return (*hi - *lo) / mean;
}

struct LogComparison {
    SteadyMean regular, irregular;
    double regular_spread = 0, irregular_spread = 0;
};

// Predicts the cut from a 1 ms model and from the seed-pattern log of the same path (through
// motion_io::ingest) and measures both over the steady part, located by position.
LogComparison compare_logs(const Cut& cut, double steady_mm, force_model::Device device) {
    const Coefficients k = test_coefficients();
    const Vec3 offset_mm = {-200, 300, 350};
    const StraightSetup setup = straight_setup(cut, 10000, 0, steady_mm);
    force_model::RunSpec spec = flat_tool_spec(cut, k, setup.box, 0.02);
    for (int i = 0; i < 3; ++i) spec.offset_mm[i] = offset_mm[i];

    const std::string log = (std::filesystem::temp_directory_path() /
                             fmt::format("cutload_phys_seed_pattern_{}.csv", ::getpid())).string();
    write_seed_pattern_csv(setup.path, log, offset_mm);
    motion_io::ReadOptions read;
    read.step_ms = 1.0;
    const motion_io::MotionModel irregular = motion_io::ingest(log, read);
    std::filesystem::remove(log);
    const motion_io::MotionModel regular = uniform_motion(setup.path, 0.001, offset_mm);

    force_model::PredictOptions opt;
    opt.device = device;
    // The fixture path starts and stops abruptly (infinite acceleration), which no smooth
    // interpolant follows; leave ingest ~30 ms of it at the end.
    const double x0 = 0.3, x1 = steady_mm - 3.0;
    LogComparison c;
    const force_model::Prediction a = force_model::predict(regular, spec, opt);
    const double a0 = time_at_x(regular, offset_mm[0], x0), a1 = time_at_x(regular, offset_mm[0], x1);
    c.regular = steady_mean(a.samples, a0, a1, cut.flutes);
    c.regular_spread = tooth_peak_spread(a.samples, a0, a1, cut.flutes);
    const force_model::Prediction b = force_model::predict(irregular, spec, opt);
    const double b0 = time_at_x(irregular, offset_mm[0], x0), b1 = time_at_x(irregular, offset_mm[0], x1);
    c.irregular = steady_mean(b.samples, b0, b1, cut.flutes);
    c.irregular_spread = tooth_peak_spread(b.samples, b0, b1, cut.flutes);
    return c;
}

std::string show(const Forces& f) { return fmt::format("({:.3f},{:.3f},{:.3f}) N", f.fx_N, f.fy_N, f.fz_N); }

// The seed's finishing cut: D 8, 2 flutes, 30 deg helix, down milling ae 1 mm, a 3 mm,
// 0.3 mm/tooth at 6000 mm/min and 10000 rpm, logged in the demo set-up's machine coordinates.
const Cut kSeedCut = down_cut(8, 2, 30, 3, 0.3, 1);

}  // namespace

TEST_CASE("physics: a log in the seed's irregular sampling pattern gives the same mean forces as a 1 ms log",
          "[physics][sampling]") {
    // 30 mm of steady cut: about 60 client cycles of log.
    const Forces closed = average_forces(kSeedCut, test_coefficients());
    for (force_model::Device device : devices_under_test()) {
        const LogComparison c = compare_logs(kSeedCut, 30.0, device);
        const double diff = relative_force_error(c.irregular.forces, c.regular.forces);
        const std::string figures = fmt::format(
            "{} seed-pattern log (30 mm) vs 1 ms log: {} vs {} diff {:.3f}%, torque {:.4f} vs {:.4f} N m; per-tooth "
            "peak spread {:.2f}% vs {:.2f}%; 1 ms log vs closed form {:.3f}%",
            device_name(device), show(c.irregular.forces), show(c.regular.forces), 100 * diff,
            c.irregular.forces.torque_Nm, c.regular.forces.torque_Nm, 100 * c.irregular_spread,
            100 * c.regular_spread, 100 * relative_force_error(c.regular.forces, closed));
        report_figure(figures);
        INFO(figures);
        REQUIRE(c.regular.tooth_periods >= 50);
        REQUIRE(c.irregular.tooth_periods >= 50);
        CHECK(diff < 0.01);
        CHECK(c.irregular.forces.torque_Nm == Approx(c.regular.forces.torque_Nm).epsilon(0.01));
        CHECK(relative_force_error(c.regular.forces, closed) < 0.02);
        CHECK(c.regular_spread < kPeakSpreadAllowed);
        CHECK(c.irregular_spread < kPeakSpreadAllowed);
    }
}

TEST_CASE("physics: a short seed-pattern log gives the same per-tooth forces as a 1 ms log",
          "[physics][sampling]") {
    for (force_model::Device device : devices_under_test()) {
        const LogComparison c = compare_logs(kSeedCut, 8.0, device);
        const double diff = relative_force_error(c.irregular.forces, c.regular.forces);
        const std::string figures = fmt::format(
            "{} seed-pattern log (8 mm) vs 1 ms log: mean diff {:.3f}%, per-tooth peak spread {:.2f}% vs {:.2f}%",
            device_name(device), 100 * diff, 100 * c.irregular_spread, 100 * c.regular_spread);
        report_figure(figures);
        INFO(figures);
        REQUIRE(c.irregular.tooth_periods >= 10);
        CHECK(diff < 0.01);
        CHECK(c.regular_spread < kPeakSpreadAllowed);
        CHECK(c.irregular_spread < kPeakSpreadAllowed);
    }
}
