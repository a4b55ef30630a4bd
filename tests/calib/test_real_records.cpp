// Calibration and comparison on records as real dynamometers export them: the steady part only (no
// idle lead-in), a charge amplifier drifting by 5 % of the mean force over the record, runout, noise,
// a 16-bit converter's step, and a spindle speed whose revolutions do not fall on samples.
#include "calib/dyno_fixture.hpp"
#include "force_model/calibrate.hpp"
#include "force_model/compare.hpp"

#include <catch2/catch.hpp>
#include <fmt/format.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>

#include <unistd.h>

using namespace cutload;
using namespace cutload::force_model;
using namespace cutload::calibtest;

namespace {

// 9000 rpm at 10 kHz: 66.67 samples per revolution.
constexpr double kRpm = 9000;
constexpr double kAxialMm = 2;
constexpr double kRadialMm = 2;
// The motion is sampled finely enough (5.4 deg of spindle angle) that the record, interpolated from
// it, carries the engine's waveform rather than a coarse polygon of it.
constexpr double kStepS = 1e-4;
// A +-1000 N range on a 16-bit converter.
constexpr double kQuantumN = 1000.0 / 32768;
// Test cuts 30 mm long: 25 mm of full engagement.
constexpr double kLengthMm = 30;

StraightCut cut_of(double feed_per_tooth_mm, Side side) {
    return straight_cut(feed_per_tooth_mm, kAxialMm, side, side == Side::Slot ? 0 : kRadialMm, kRpm, kStepS, kLengthMm);
}

std::pair<double, double> steady_span_s(double feed_per_tooth_mm) {
    return full_engagement_span_s(feed_per_tooth_mm, kRpm, kLengthMm);
}

void report(const std::string& line) {
    static const bool verbose = std::getenv("CUTLOAD_CALIB_VERBOSE") != nullptr;
    if (verbose) std::printf("CALIB %s\n", line.c_str());
}

// Per process: worktrees may run the suite at once.
std::filesystem::path scratch_dir(const char* name) {
    const auto dir = std::filesystem::temp_directory_path() / fmt::format("{}_{}", name, ::getpid());
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    return dir;
}

Prediction predict_cpu(const StraightCut& cut) {
    PredictOptions o;
    o.device = Device::Cpu;
    return predict(cut.motion, cut.spec, o);
}

CutTest cut_test(double feed_per_tooth_mm, Side side) {
    CutTest t;
    t.spindle_rpm = kRpm;
    t.feed_mm_min = feed_per_tooth_mm * test_tool().flutes * kRpm;
    t.axial_mm = kAxialMm;
    t.radial_mm = side == Side::Slot ? 0 : kRadialMm;
    t.mode = side == Side::Slot ? Immersion::Slot : side == Side::Up ? Immersion::Up : Immersion::Down;
    return t;
}

// A real export: the steady part only, drifting, quantized.
DynoOptions steady_export(double feed_per_tooth_mm, unsigned seed) {
    const auto [from_s, to_s] = steady_span_s(feed_per_tooth_mm);
    DynoOptions o;
    o.record_from_s = from_s;
    o.record_to_s = to_s;
    o.drift_rel = {0.05, -0.05, 0.05};
    o.quantum_N = kQuantumN;
    o.seed = seed;
    return o;
}

// Independent reference: the mean of the noise-free prediction over whole revolutions inside its
// full-engagement span (the samples are equally spaced in time at constant speed, so a plain mean
// over whole revolutions is the revolution mean).
std::array<double, 3> true_mean_force(const Prediction& p, double feed_per_tooth_mm) {
    const auto [from_s, to_s] = steady_span_s(feed_per_tooth_mm);
    const double rev_s = 60.0 / kRpm;
    const double end_s = from_s + std::floor((to_s - from_s) / rev_s) * rev_s;
    std::array<double, 3> sum{};
    std::size_t n = 0;
    for (const auto& s : p.samples)
        if (s.t_s >= from_s && s.t_s < end_s) {
            sum[0] += s.fx_N;
            sum[1] += s.fy_N;
            sum[2] += s.fz_N;
            ++n;
        }
    REQUIRE(n > 100);
    return {sum[0] / n, sum[1] / n, sum[2] / n};
}

std::array<double, 3> times(const Regressors& r, const std::array<double, 6>& k) {
    std::array<double, 3> f{};
    for (std::size_t ax = 0; ax < 3; ++ax)
        for (std::size_t j = 0; j < 6; ++j) f[ax] += r[ax][j] * k[j];
    return f;
}

double norm(const std::array<double, 3>& a) { return std::hypot(a[0], a[1], a[2]); }

Measurement read_mapped(const std::string& file) {
    Measurement m = read_measurement(file);
    map_to_tool_machine_axes(m, kSeedAxes);
    return m;
}

// What the first detector makes of a record: "no steady cut", or the error of its mean force.
std::string first_detector_outcome(const Measurement& m, const std::array<double, 3>& mean_true) {
    SteadyOptions first;
    first.detector = SteadyDetector::FirstRevolution;
    try {
        const SteadyForce s = steady_mean_force(m, kRpm, first);
        return fmt::format("{} rev, zero {}, mean force off by {:.1f} % of |F|", s.revolutions,
                           s.zeroed ? "removed" : "not removed",
                           100 * std::hypot(s.mean_N[0] - mean_true[0], s.mean_N[1] - mean_true[1],
                                            s.mean_N[2] - mean_true[2]) /
                               norm(mean_true));
    } catch (const SteadyError& e) {
        return e.what();
    }
}

// It fails when it finds no steady cut, or a mean force more than 3 % of |F| off the truth (the
// tolerance the coefficients are held to).
bool first_detector_fails(const Measurement& m, const std::array<double, 3>& mean_true) {
    SteadyOptions first;
    first.detector = SteadyDetector::FirstRevolution;
    try {
        const SteadyForce s = steady_mean_force(m, kRpm, first);
        return std::hypot(s.mean_N[0] - mean_true[0], s.mean_N[1] - mean_true[1], s.mean_N[2] - mean_true[2]) >
               0.03 * norm(mean_true);
    } catch (const SteadyError& e) {
        return std::string(e.what()).find("no steady cut") != std::string::npos;
    }
}

SteadyOptions robust_options(const CutTest& test) {
    SteadyOptions o;
    o.flutes = test_tool().flutes;
    o.air_fraction = tooth_air_fraction(test_tool(), test);
    return o;
}

}  // namespace

TEST_CASE("steady-only drifting records: three down-milling feeds recover the six coefficients within 3 % and predict "
          "two other feeds within 3 %",
          "[calib][real]") {
    const auto dir = scratch_dir("cutload_calib_real");
    const double feeds[] = {0.04, 0.10, 0.16};
    std::vector<Regressors> regs;
    std::vector<std::array<double, 3>> means;
    for (std::size_t i = 0; i < std::size(feeds); ++i) {
        const CutTest test = cut_test(feeds[i], Side::Down);
        const Prediction truth = predict_cpu(cut_of(feeds[i], Side::Down));
        const std::string file = (dir / fmt::format("down{}.csv", i)).string();
        const DynoOptions dyno = steady_export(feeds[i], 500 + static_cast<unsigned>(i));
        const DynoRecord rec = write_dyno_file(truth, file, dyno);
        const Measurement m = read_mapped(file);
        REQUIRE(m.t_s(0) == Approx(rec.t_first_s).margin(1e-6));   // no lead-in: the file starts cutting

        // The first detector takes the first revolution for idle: on these records it finds no steady cut,
        // or a mean force that is not the cut's.
        const auto mean_true = true_mean_force(truth, feeds[i]);
        report(fmt::format("down c={}: first detector: {}", feeds[i], first_detector_outcome(m, mean_true)));
        CHECK(first_detector_fails(m, mean_true));

        const SteadyForce steady = steady_mean_force(m, kRpm, robust_options(test));
        CHECK_FALSE(steady.window_given);
        CHECK(steady.zero.source == ZeroSource::Estimated);
        CHECK(steady.zero.drift_source == DriftSource::Cut);
        // Almost the whole record is steady (less the smoothing trim).
        const double record_revs = (rec.t_last_s - rec.t_first_s) * kRpm / 60;
        CHECK(steady.revolutions >= record_revs - 8);
        // Drift and zero against what the generator put in, both in tool / machine axes.
        const auto drift_true = to_tool_machine_axes(rec.drift_N_per_s, kSeedAxes);
        const double t_c = 0.5 * (steady.t_start_s + steady.t_end_s);
        const auto zero_true = to_tool_machine_axes(rec.offset_at(t_c, dyno), kSeedAxes);
        report(fmt::format("down c={}: {} rev {:.4f}-{:.4f} s, zero ({:.3f}, {:.3f}, {:.3f}) N [true ({:.3f}, {:.3f}, "
                           "{:.3f})], drift ({:.2f}, {:.2f}, {:.2f}) N/s [true ({:.2f}, {:.2f}, {:.2f})]",
                           feeds[i], steady.revolutions, steady.t_start_s, steady.t_end_s, steady.zero_N[0],
                           steady.zero_N[1], steady.zero_N[2], zero_true[0], zero_true[1], zero_true[2],
                           steady.zero.drift_N_per_s[0], steady.zero.drift_N_per_s[1], steady.zero.drift_N_per_s[2],
                           drift_true[0], drift_true[1], drift_true[2]));
        for (std::size_t ax = 0; ax < 3; ++ax) {
            CHECK(std::abs(steady.zero.drift_N_per_s[ax] - drift_true[ax]) < 0.1 * norm(drift_true));
            CHECK(std::abs(steady.zero_N[ax] - zero_true[ax]) < 0.25);
        }
        regs.push_back(engine_regressors(test_tool(), test));
        means.push_back(to_feed_frame(steady.mean_N, test.feed_direction_deg));
    }
    const CalibrationFit fit = fit_mean_forces(regs, means, "real");
    const auto k = coefficients_of(fit.material), want = coefficients_of(true_material());
    std::string errors;
    for (std::size_t j = 0; j < 6; ++j) {
        errors += fmt::format(" {} {:+.2f} %", kCoefficientKeys[j], 100 * (k[j] / want[j] - 1));
        INFO(kCoefficientKeys[j] << ": identified " << k[j] << ", true " << want[j]);
        CHECK(std::abs(k[j] / want[j] - 1) < 0.03);
    }
    report(fmt::format("coefficient errors:{}; rms residual {:.3f} N, condition {:.2f}", errors, fit.rms_residual_N,
                       fit.condition_number));

    // Two feeds not used in the fit: the identified coefficients predict their mean forces.
    for (double c : {0.07, 0.13}) {
        const Prediction truth = predict_cpu(cut_of(c, Side::Down));
        const auto want_N = true_mean_force(truth, c);
        const auto got_N = times(engine_regressors(test_tool(), cut_test(c, Side::Down)), k);
        report(fmt::format("c={}: predicted mean ({:.2f}, {:.2f}, {:.2f}) N, true ({:.2f}, {:.2f}, {:.2f}) N, errors "
                           "{:+.2f} {:+.2f} {:+.2f} % of |F|, |F| {:+.2f} %",
                           c, got_N[0], got_N[1], got_N[2], want_N[0], want_N[1], want_N[2],
                           100 * (got_N[0] - want_N[0]) / norm(want_N), 100 * (got_N[1] - want_N[1]) / norm(want_N),
                           100 * (got_N[2] - want_N[2]) / norm(want_N), 100 * (norm(got_N) / norm(want_N) - 1)));
        for (std::size_t ax = 0; ax < 3; ++ax) {
            INFO("feed " << c << " axis " << ax << ": predicted " << got_N[ax] << ", true " << want_N[ax]);
            CHECK(std::abs(got_N[ax] - want_N[ax]) < 0.03 * std::max(std::abs(want_N[ax]), 0.3 * norm(want_N)));
        }
    }
    std::filesystem::remove_all(dir);
}

TEST_CASE("the air between tooth passes is found with the spindle up to 1 % off its nominal speed", "[calib][real]") {
    const auto dir = scratch_dir("cutload_calib_speed");
    const double c = 0.06;
    const Prediction truth = predict_cpu(cut_of(c, Side::Down));
    const DynoOptions dyno = steady_export(c, 650);
    const std::string file = (dir / "down.csv").string();
    const DynoRecord rec = write_dyno_file(truth, file, dyno);
    const Measurement m = read_mapped(file);
    for (double off : {-0.01, 0.003, 0.01}) {
        // The spindle ran at kRpm; the test is described at a speed `off` away from it.
        CutTest test = cut_test(c, Side::Down);
        test.spindle_rpm = kRpm * (1 + off);
        const SteadyForce steady = steady_mean_force(m, test.spindle_rpm, robust_options(test));
        REQUIRE(steady.zero.source == ZeroSource::Estimated);
        const auto zero_true = to_tool_machine_axes(rec.offset_at(0.5 * (steady.t_start_s + steady.t_end_s), dyno), kSeedAxes);
        INFO("speed off by " << 100 * off << " %: zero " << steady.zero_N[0] << ", " << steady.zero_N[1] << ", "
                             << steady.zero_N[2] << " N, true " << zero_true[0] << ", " << zero_true[1] << ", "
                             << zero_true[2]);
        for (std::size_t ax = 0; ax < 3; ++ax) CHECK(std::abs(steady.zero_N[ax] - zero_true[ax]) < 0.25);
    }
    std::filesystem::remove_all(dir);
}

TEST_CASE("a record with an idle tail but no lead-in takes its zero from the tail, carried along the drift",
          "[calib][real]") {
    const auto dir = scratch_dir("cutload_calib_tail");
    const double c = 0.08;
    const CutTest test = cut_test(c, Side::Slot);
    const Prediction truth = predict_cpu(cut_of(c, Side::Slot));
    DynoOptions dyno = steady_export(c, 610);
    dyno.record_to_s.reset();   // the exit and the idle tail stay in the record
    const std::string file = (dir / "slot_tail.csv").string();
    const DynoRecord rec = write_dyno_file(truth, file, dyno);
    const Measurement m = read_mapped(file);

    const auto mean_true = true_mean_force(truth, c);
    // The first detector takes the first revolution for idle; here the idle tail is what differs from
    // it most.
    report(fmt::format("slot tail: first detector: {}", first_detector_outcome(m, mean_true)));
    CHECK(first_detector_fails(m, mean_true));
    const SteadyForce steady = steady_mean_force(m, kRpm, robust_options(test));
    CHECK(steady.zero.source == ZeroSource::IdleTail);
    CHECK(steady.zero.drift_source == DriftSource::Cut);
    const auto [from_s, to_s] = steady_span_s(c);
    // The window ends before the exit ramp.
    CHECK(steady.t_end_s <= to_s + dyno.delay_s);
    const double t_c = 0.5 * (steady.t_start_s + steady.t_end_s);
    const auto zero_true = to_tool_machine_axes(rec.offset_at(t_c, dyno), kSeedAxes);
    report(fmt::format("slot tail: zero ({:.3f}, {:.3f}, {:.3f}) N [true ({:.3f}, {:.3f}, {:.3f})], mean ({:.2f}, "
                       "{:.2f}, {:.2f}) N [true ({:.2f}, {:.2f}, {:.2f})]",
                       steady.zero_N[0], steady.zero_N[1], steady.zero_N[2], zero_true[0], zero_true[1], zero_true[2],
                       steady.mean_N[0], steady.mean_N[1], steady.mean_N[2], mean_true[0], mean_true[1], mean_true[2]));
    for (std::size_t ax = 0; ax < 3; ++ax) {
        CHECK(std::abs(steady.zero_N[ax] - zero_true[ax]) < 0.5);
        CHECK(std::abs(steady.mean_N[ax] - mean_true[ax]) < 0.01 * norm(mean_true) + 0.5);
    }
    std::filesystem::remove_all(dir);
}

TEST_CASE("a slot record that is all cutting needs its zero offset given, and then uses it", "[calib][real]") {
    const auto dir = scratch_dir("cutload_calib_given");
    const double c = 0.1;
    const CutTest test = cut_test(c, Side::Slot);
    const Prediction truth = predict_cpu(cut_of(c, Side::Slot));
    const DynoOptions dyno = steady_export(c, 620);
    const std::string file = (dir / "slot.csv").string();
    const DynoRecord rec = write_dyno_file(truth, file, dyno);
    const Measurement m = read_mapped(file);

    // A slot has no air between tooth passes: nothing in the record tells the zero.
    SteadyOptions opt = robust_options(test);
    CHECK(opt.air_fraction == 0);
    try {
        steady_mean_force(m, kRpm, opt);
        FAIL("a slot record with no idle recording was accepted without a zero offset");
    } catch (const SteadyError& e) {
        CHECK(e.need == SteadyError::Need::Zero);
        CHECK_THAT(e.what(), Catch::Contains("no zero offset") && Catch::Contains("give the zero offset"));
    }
    // Air claimed where there is none (the conditions of a down-milling test): the folded waveform has
    // no stretch as flat and quiet as the noise, so no zero is made up.
    opt.air_fraction = tooth_air_fraction(test_tool(), cut_test(c, Side::Down));
    REQUIRE(opt.air_fraction > 0.5);
    CHECK_THROWS_WITH(steady_mean_force(m, kRpm, opt), Catch::Contains("not flat enough"));
    opt.air_fraction = 0;

    // Given: the amplifier's reading with no load at the record's start, in its own channels.
    opt.zero_N = to_tool_machine_axes(rec.offset_at(rec.t_first_s, dyno), kSeedAxes);
    const SteadyForce steady = steady_mean_force(m, kRpm, opt);
    CHECK(steady.zero.source == ZeroSource::Given);
    const auto mean_true = true_mean_force(truth, c);
    for (std::size_t ax = 0; ax < 3; ++ax) CHECK(std::abs(steady.mean_N[ax] - mean_true[ax]) < 0.01 * norm(mean_true));
    std::filesystem::remove_all(dir);
}

TEST_CASE("a full record with lead-in and tail: the drift is the line between them, and an explicit window is used as "
          "given",
          "[calib][real]") {
    const auto dir = scratch_dir("cutload_calib_full");
    const double c = 0.1;
    const CutTest test = cut_test(c, Side::Slot);
    const Prediction truth = predict_cpu(cut_of(c, Side::Slot));
    DynoOptions dyno;
    dyno.drift_rel = {-0.05, 0.05, 0.05};
    dyno.quantum_N = kQuantumN;
    dyno.seed = 630;
    const std::string file = (dir / "slot_full.csv").string();
    const DynoRecord rec = write_dyno_file(truth, file, dyno);
    const Measurement m = read_mapped(file);
    const auto drift_true = to_tool_machine_axes(rec.drift_N_per_s, kSeedAxes);
    const auto mean_true = true_mean_force(truth, c);

    const SteadyForce detected = steady_mean_force(m, kRpm, robust_options(test));
    CHECK(detected.zero.source == ZeroSource::LeadIn);
    CHECK(detected.zero.drift_source == DriftSource::Idle);
    for (std::size_t ax = 0; ax < 3; ++ax) {
        CHECK(std::abs(detected.zero.drift_N_per_s[ax] - drift_true[ax]) < 0.1 * norm(drift_true));
        CHECK(std::abs(detected.mean_N[ax] - mean_true[ax]) < 0.01 * norm(mean_true));
    }

    // An explicit window: exactly its whole revolutions, zero and drift as before.
    const auto [from_s, to_s] = steady_span_s(c);
    SteadyOptions opt = robust_options(test);
    opt.t_start_s = from_s + dyno.delay_s + 0.01;
    opt.t_end_s = to_s + dyno.delay_s - 0.01;
    const SteadyForce given = steady_mean_force(m, kRpm, opt);
    CHECK(given.window_given);
    const double sample_s = 1 / m.rate_Hz, rev_s = 60 / kRpm;
    CHECK(given.t_start_s >= *opt.t_start_s - sample_s);
    CHECK(given.t_start_s < *opt.t_start_s + rev_s);
    CHECK(given.t_end_s <= *opt.t_end_s + sample_s);
    CHECK(given.t_end_s > *opt.t_end_s - rev_s);
    CHECK(given.zero.source == ZeroSource::LeadIn);
    for (std::size_t ax = 0; ax < 3; ++ax) CHECK(std::abs(given.mean_N[ax] - mean_true[ax]) < 0.01 * norm(mean_true));

    opt.t_start_s = 100.0;
    opt.t_end_s = 101.0;
    CHECK_THROWS_WITH(steady_mean_force(m, kRpm, opt), Catch::Contains("no whole revolution in the steady window") &&
                                                           Catch::Contains("the record covers"));
    std::filesystem::remove_all(dir);
}

TEST_CASE("compare removes a drifting zero: a line through the idle lead-in and tail, or through the air between tooth "
          "passes of a steady-only record",
          "[calib][real][compare]") {
    const auto dir = scratch_dir("cutload_calib_real_compare");
    const double c = 0.08;
    const Prediction truth = predict_cpu(cut_of(c, Side::Down));
    const PredictedTrace trace = predicted_trace(truth);

    // Full record: idle lead-in and tail, drifting.
    DynoOptions full;
    full.drift_rel = {0.05, -0.05, 0.05};
    full.quantum_N = kQuantumN;
    full.seed = 640;
    const DynoRecord rec_full = write_dyno_file(truth, (dir / "full.csv").string(), full);
    const Measurement m_full = read_mapped((dir / "full.csv").string());
    CompareOptions opt;
    opt.offset_s = -full.delay_s;
    opt.averaging = Averaging::Revolution;
    const Comparison cf = compare(trace, m_full, opt);
    CHECK(cf.zero.source == ZeroSource::LeadIn);
    CHECK(cf.zero.drift_source == DriftSource::Idle);
    const auto drift_full = to_tool_machine_axes(rec_full.drift_N_per_s, kSeedAxes);
    for (std::size_t ax = 0; ax < 3; ++ax)
        CHECK(std::abs(cf.zero.drift_N_per_s[ax] - drift_full[ax]) < 0.05 * norm(drift_full));
    // Drift removed, the revolution means agree: what is left is noise and the per-revolution runout.
    const double mean_N = norm(true_mean_force(truth, c));
    for (int ax = 0; ax < 3; ++ax) {
        CHECK(std::abs(cf.overall.axes[ax].mean_error_N) < 0.01 * mean_N);
        CHECK(cf.overall.axes[ax].rmse_N < 0.02 * mean_N);
    }

    // Steady-only record: the only air is between tooth passes; the drift comes from it too.
    const DynoOptions steady = steady_export(c, 641);
    const DynoRecord rec = write_dyno_file(truth, (dir / "steady.csv").string(), steady);
    const Measurement m = read_mapped((dir / "steady.csv").string());
    opt.offset_s = -steady.delay_s;
    const Comparison cs = compare(trace, m, opt);
    CHECK(cs.zero.source == ZeroSource::Estimated);
    CHECK(cs.zero.drift_source == DriftSource::Idle);
    const auto drift = to_tool_machine_axes(rec.drift_N_per_s, kSeedAxes);
    // The zero at its reference time (prediction time; the record's is that less the offset).
    const auto zero_true = to_tool_machine_axes(rec.offset_at(cs.zero.t_s - *opt.offset_s, steady), kSeedAxes);
    report(fmt::format("compare steady-only: zero ({:.3f}, {:.3f}, {:.3f}) N [true ({:.3f}, {:.3f}, {:.3f})], drift "
                       "({:.2f}, {:.2f}, {:.2f}) N/s [true ({:.2f}, {:.2f}, {:.2f})]",
                       cs.zero_N[0], cs.zero_N[1], cs.zero_N[2], zero_true[0], zero_true[1], zero_true[2],
                       cs.zero.drift_N_per_s[0], cs.zero.drift_N_per_s[1], cs.zero.drift_N_per_s[2], drift[0], drift[1],
                       drift[2]));
    for (std::size_t ax = 0; ax < 3; ++ax) {
        CHECK(std::abs(cs.zero.drift_N_per_s[ax] - drift[ax]) < 0.2 * norm(drift));
        CHECK(std::abs(cs.zero_N[ax] - zero_true[ax]) < 0.25);
    }
    for (int ax = 0; ax < 3; ++ax) CHECK(std::abs(cs.overall.axes[ax].mean_error_N) < 0.01 * mean_N);

    // Given: used as the zero at the record's first sample.
    opt.zero_N = to_tool_machine_axes(rec.offset_at(rec.t_first_s, steady), kSeedAxes);
    const Comparison cg = compare(trace, m, opt);
    CHECK(cg.zero.source == ZeroSource::Given);
    for (int ax = 0; ax < 3; ++ax) CHECK(std::abs(cg.overall.axes[ax].mean_error_N) < 0.01 * mean_N);
    std::filesystem::remove_all(dir);
}
