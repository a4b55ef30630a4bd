// compare(): metrics on cases with known answers, the zero-phase filter's response, alignment by
// cross-correlation, per-period averaging, per-block scopes, FORCES.csv read back, and errors.
#include "force_model/compare.hpp"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <numbers>

using namespace cutload::force_model;

namespace {

constexpr double pi = std::numbers::pi;

using Signal = std::function<double(double t_s, int axis)>;

// A prediction sampled every dt_s over [0, t_end_s] at constant spindle speed.
PredictedTrace trace_of(const Signal& f, double t_end_s, double dt_s, double rpm = 6000,
                        std::function<int(double)> block_of = nullptr) {
    PredictedTrace p;
    p.block_names = {"N10", "N20"};
    const auto n = static_cast<std::size_t>(std::llround(t_end_s / dt_s)) + 1;
    for (std::size_t i = 0; i < n; ++i) {
        ForceSample s;
        s.t_s = static_cast<double>(i) * dt_s;
        s.spindle_angle_deg = 6.0 * rpm * s.t_s;
        s.block = block_of ? block_of(s.t_s) : 0;
        s.fx_N = static_cast<float>(f(s.t_s, 0));
        s.fy_N = static_cast<float>(f(s.t_s, 1));
        s.fz_N = static_cast<float>(f(s.t_s, 2));
        p.samples.push_back(s);
    }
    return p;
}

// A measurement already in tool / machine axes: sample i at t0_s + i / rate_Hz.
Measurement measurement_of(const Signal& f, double t0_s, double t_end_s, double rate_Hz) {
    Measurement m;
    m.source = "synthetic";
    m.rate_Hz = rate_Hz;
    m.t0_s = t0_s;
    m.tool_machine_axes = true;
    const auto n = static_cast<std::size_t>(std::floor((t_end_s - t0_s) * rate_Hz)) + 1;
    for (std::size_t i = 0; i < n; ++i) {
        const double t = m.t_s(i);
        m.fx_N.push_back(static_cast<float>(f(t, 0)));
        m.fy_N.push_back(static_cast<float>(f(t, 1)));
        m.fz_N.push_back(static_cast<float>(f(t, 2)));
    }
    return m;
}

// 100 Hz sines with different amplitudes and phases per axis; whole periods over 0.1 s.
double sines(double t, int axis) { return (10.0 + 5.0 * axis) * std::sin(2 * pi * 100 * t + axis); }

CompareOptions raw(double offset_s = 0) {
    CompareOptions o;
    o.offset_s = offset_s;
    o.cutoff_Hz = 0;
    return o;
}

// A cut-like burst: tooth-passing pulses under a smooth envelope, different on each axis.
double burst(double t, int axis) {
    const double env = std::exp(-std::pow((t - 0.12) / 0.04, 2));
    const double tooth = std::pow(std::max(0.0, std::sin(2 * pi * 200 * t + 0.7 * axis)), 2);
    return (40.0 - 10.0 * axis) * env * (0.3 + tooth);
}

}  // namespace

TEST_CASE("identical signals give zero error and correlation 1", "[calib][compare]") {
    const PredictedTrace p = trace_of(sines, 0.11, 5e-5);
    const Measurement m = measurement_of(sines, 0, 0.1, 10000);
    const Comparison c = compare(p, m, raw());
    REQUIRE(c.overall.samples == m.size());
    for (int ax = 0; ax < 4; ++ax) {
        INFO("axis " << ax);
        CHECK(std::abs(c.overall.axes[ax].mean_error_N) < 1e-5);
        CHECK(c.overall.axes[ax].rmse_N < 1e-5);
        CHECK(c.overall.axes[ax].nrmse < 1e-6);
        CHECK(std::abs(c.overall.axes[ax].peak_error_N) < 1e-5);
        CHECK(c.overall.axes[ax].correlation == Approx(1.0).margin(1e-9));
    }
}

TEST_CASE("a prediction 10 % high gives the known errors", "[calib][compare]") {
    const PredictedTrace p = trace_of([](double t, int a) { return 1.1 * sines(t, a); }, 0.11, 5e-5);
    // 1001 samples: whole periods plus one sample at a zero crossing.
    const Measurement m = measurement_of(sines, 0, 0.1, 10000);
    const Comparison c = compare(p, m, raw());
    for (int ax = 0; ax < 3; ++ax) {
        const double amp = 10.0 + 5.0 * ax;
        const double ptp = c.overall.axes[ax].peak_measured_N * 2;   // symmetric sine
        INFO("axis " << ax);
        CHECK(c.overall.axes[ax].mean_error_N == Approx(0).margin(1e-3 * amp));
        CHECK(c.overall.axes[ax].rmse_N == Approx(0.1 * amp / std::sqrt(2.0)).epsilon(2e-3));
        // NRMSE = 0.1 rms / peak-to-peak = 0.1 / (2 sqrt 2) for a sine.
        CHECK(c.overall.axes[ax].nrmse == Approx(0.1 / (2 * std::sqrt(2.0))).epsilon(2e-3));
        CHECK(c.overall.axes[ax].peak_error_N == Approx(0.1 * ptp / 2).epsilon(1e-3));
        CHECK(c.overall.axes[ax].correlation == Approx(1.0).margin(1e-6));
    }
    // A constant 2 N bias on x only: mean error 2 N, rmse 2 N, correlation still 1.
    const PredictedTrace b = trace_of([](double t, int a) { return sines(t, a) + (a == 0 ? 2.0 : 0.0); }, 0.11, 5e-5);
    const Comparison cb = compare(b, m, raw());
    CHECK(cb.overall.axes[0].mean_error_N == Approx(2.0).epsilon(1e-4));
    CHECK(cb.overall.axes[0].rmse_N == Approx(2.0).epsilon(1e-4));
    CHECK(cb.overall.axes[0].correlation == Approx(1.0).margin(1e-6));
    CHECK(cb.overall.axes[1].rmse_N < 1e-5);
}

TEST_CASE("the zero-phase low-pass has unit DC gain, -6 dB at the cut-off and no delay",
          "[calib][compare][filter]") {
    const double fs = 10000, fc = 500;
    auto amplitude_after = [&](double f_Hz) {
        std::vector<float> x(20000);
        for (std::size_t i = 0; i < x.size(); ++i) x[i] = static_cast<float>(std::sin(2 * pi * f_Hz * i / fs));
        lowpass_zero_phase(x, fs, fc);
        // Amplitude and phase by projection on the middle half (away from the ends).
        double s = 0, c = 0;
        for (std::size_t i = 5000; i < 15000; ++i) {
            s += x[i] * std::sin(2 * pi * f_Hz * i / fs);
            c += x[i] * std::cos(2 * pi * f_Hz * i / fs);
        }
        return std::pair<double, double>{2 * std::hypot(s, c) / 10000, std::atan2(c, s)};
    };
    // Forward-backward squares a 4th-order Butterworth: |H|^2 = 1 / (1 + (f / fc)^8).
    for (double f : {50.0, 250.0, 500.0, 1000.0}) {
        const auto [amp, phase] = amplitude_after(f);
        INFO("f = " << f << " Hz");
        CHECK(amp == Approx(1.0 / (1.0 + std::pow(f / fc, 8))).margin(2e-3));
        if (amp > 0.01) CHECK(std::abs(phase) < 1e-3);
    }
    std::vector<float> dc(3000, 7.5f);
    lowpass_zero_phase(dc, fs, fc);
    CHECK(dc.front() == Approx(7.5f).epsilon(1e-5));
    CHECK(dc[1500] == Approx(7.5f).epsilon(1e-5));
    CHECK(dc.back() == Approx(7.5f).epsilon(1e-5));
    CHECK_THROWS_WITH(lowpass_zero_phase(dc, fs, 6000), Catch::Contains("cut-off 6000 Hz must be in (0, 5000)"));
}

TEST_CASE("the time offset is found by cross-correlation within one sample", "[calib][compare][align]") {
    const double fs = 10000;
    for (double delay_s : {0.0, 0.01234, -0.0377, 0.15}) {
        // The measurement records the same burst delay_s later on its own clock, from -0.1 s.
        const PredictedTrace p = trace_of(burst, 0.24, 3e-5);
        const Measurement m = measurement_of([&](double t, int a) { return burst(t - delay_s, a); }, -0.1, 0.5, fs);
        double score = 0;
        const double offset = find_offset_s(p, m, &score);
        INFO("delay " << delay_s << " s: offset " << offset << " s, score " << score);
        CHECK(std::abs(offset + delay_s) < 1.0 / fs);
        CHECK(score > 0.99);
        CompareOptions o;
        o.cutoff_Hz = 2000;
        const Comparison c = compare(p, m, o);
        CHECK(c.offset_found);
        CHECK(c.overall.axes[3].correlation > 0.999);
        CHECK(c.overall.axes[3].nrmse < 0.01);
    }
}

TEST_CASE("per-revolution and per-tooth averaging remove the periodic part", "[calib][compare]") {
    // 6000 rpm: one revolution per 10 ms. Measured: 5 + 3 sin(rev); predicted: 6 + 4 sin(2 rev).
    auto rev_angle = [](double t) { return 2 * pi * 100 * t; };
    const PredictedTrace p = trace_of([&](double t, int) { return 6 + 4 * std::sin(2 * rev_angle(t)); }, 0.21, 2e-5);
    // 20 whole revolutions and half of one more, which is dropped.
    const Measurement m =
        measurement_of([&](double t, int) { return 5 + 3 * std::sin(rev_angle(t)); }, 0, 0.2049, 10000);
    CompareOptions o = raw();
    o.averaging = Averaging::Revolution;
    const Comparison c = compare(p, m, o);
    CHECK(c.overall.samples == 20);
    CHECK(c.overall.axes[0].mean_error_N == Approx(1.0).epsilon(1e-3));
    CHECK(c.overall.axes[0].rmse_N == Approx(1.0).epsilon(1e-3));
    o.averaging = Averaging::ToothPeriod;
    o.flutes = 2;
    const Comparison t = compare(p, m, o);
    CHECK(t.overall.samples == 40);
    // Half-revolution means of the measured 3 sin(rev) alternate +-6/pi; the prediction's are flat.
    CHECK(t.overall.axes[0].mean_error_N == Approx(1.0).margin(0.01));
    CHECK(t.overall.axes[0].rmse_N == Approx(std::sqrt(1.0 + std::pow(6 / pi, 2))).epsilon(0.01));
    o.flutes = 0;
    CHECK_THROWS_WITH(compare(p, m, o), Catch::Contains("number of flutes"));
}

TEST_CASE("metrics per block and the JSON / CSV reports", "[calib][compare]") {
    // Block N10 for t < 0.05 s predicts exactly; N20 predicts 20 % high.
    auto block_of = [](double t) { return t < 0.05 ? 0 : 1; };
    const PredictedTrace p =
        trace_of([&](double t, int a) { return (block_of(t) == 0 ? 1.0 : 1.2) * sines(t, a); }, 0.11, 5e-5, 6000, block_of);
    const Measurement m = measurement_of(sines, 0, 0.1, 10000);
    const Comparison c = compare(p, m, raw());
    REQUIRE(c.blocks.size() == 2);
    CHECK(c.blocks[0].scope == "N10");
    CHECK(c.blocks[0].axes[1].rmse_N < 0.05);
    CHECK(c.blocks[1].scope == "N20");
    CHECK(c.blocks[1].axes[1].rmse_N == Approx(0.2 * 15 / std::sqrt(2.0)).epsilon(0.02));
    CHECK(c.blocks[1].t_start_s == Approx(0.05).margin(2e-4));

    const nlohmann::json j = to_json(c);
    CHECK(j["offset_source"] == "given");
    CHECK(j["blocks"].size() == 2);
    CHECK(j["overall"]["resultant"]["correlation"].get<double>() == Approx(c.overall.axes[3].correlation));
    CHECK(j["blocks"][1]["y"]["rmse_N"].get<double>() == Approx(c.blocks[1].axes[1].rmse_N));
    const auto dir = std::filesystem::temp_directory_path() / "cutload_calib_compare";
    std::filesystem::create_directories(dir);
    write_comparison_csv(c, (dir / "cmp.csv").string());
    write_comparison_trace_csv(c, p.block_names, (dir / "trace.csv").string());
    std::ifstream in(dir / "cmp.csv");
    std::string header, first;
    std::getline(in, header);
    std::getline(in, first);
    CHECK(header.rfind("scope,axis,samples,", 0) == 0);
    CHECK(first.rfind("overall,x,1001,", 0) == 0);
    std::filesystem::remove_all(dir);
}

TEST_CASE("FORCES.csv is read back, bad windows and unmapped measurements are errors", "[calib][compare]") {
    Prediction pred;
    pred.block_names = {"N1 (a, b)"};
    for (int i = 0; i < 5; ++i) {
        ForceSample s;
        s.t_s = i * 0.001;
        s.spindle_angle_deg = i * 60.0;
        s.block = 0;
        s.fx_N = static_cast<float>(i);
        s.fy_N = 2.0f * i;
        s.fz_N = -1.0f;
        pred.samples.push_back(s);
    }
    const auto dir = std::filesystem::temp_directory_path() / "cutload_calib_forces";
    std::filesystem::create_directories(dir);
    const std::string path = (dir / "FORCES.csv").string();
    write_forces_csv(pred, path);
    const PredictedTrace back = read_forces_csv(path);
    REQUIRE(back.samples.size() == 5);
    CHECK(back.block_names == pred.block_names);
    CHECK(back.samples[3].fy_N == Approx(6.0f));
    CHECK(back.samples[4].spindle_angle_deg == Approx(240.0));
    {
        std::ofstream bad(path);
        bad << "t_s,spindle_angle_deg,block,fx_N,fy_N\n";
    }
    CHECK_THROWS_WITH(read_forces_csv(path), Catch::Contains(":1: no `fz_N` column"));
    {
        std::ofstream bad(path);
        bad << "t_s,spindle_angle_deg,block,fx_N,fy_N,fz_N\n0,0,,1,2,3\n0.001,1,,1,-4e40,3\n";
    }
    CHECK_THROWS_WITH(read_forces_csv(path), Catch::Contains(":3:") && Catch::Contains("column 5 (fy_N): force -4e+40 N"));
    {
        std::ofstream bad(path);
        bad << "t_s,spindle_angle_deg,block,fx_N,fy_N,fz_N\n0,0,,1,2,3\n1e12,1,,1,2,3\n";
    }
    CHECK_THROWS_WITH(read_forces_csv(path), Catch::Contains(":3:") && Catch::Contains("time 1e+12 s is beyond"));
    std::filesystem::remove_all(dir);

    const PredictedTrace p = trace_of(sines, 0.11, 5e-5);
    const Measurement m = measurement_of(sines, 0, 0.1, 10000);
    CompareOptions o = raw();
    o.t_start_s = 0.5;
    o.t_end_s = 0.6;
    CHECK_THROWS_WITH(compare(p, m, o), Catch::Contains("empty comparison window"));
    o = raw(10.0);
    CHECK_THROWS_WITH(compare(p, m, o), Catch::Contains("does not overlap the prediction"));
    Measurement unmapped = m;
    unmapped.tool_machine_axes = false;
    CHECK_THROWS_WITH(compare(p, unmapped, raw()), Catch::Contains("map the measurement"));
}
