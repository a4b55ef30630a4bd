// Synthetic dynamometer records for the compare / calibrate tests: straight cuts predicted by the
// engine with known coefficients, turned into what a table dynamometer under the workpiece records
// (force on the workpiece, dynamometer axes, constant rate), with runout, noise, a zero offset and a
// time shift, written as a DynoWare-style CSV export. Real exports may also be the steady part only
// (no idle lead-in), drift linearly from the amplifier's reset, and carry the converter's step:
// DynoOptions::record_from_s / record_to_s, drift_rel and quantum_N.
#pragma once

#include "force_model/force_model.hpp"
#include "force_model/measurement.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <numbers>
#include <optional>
#include <random>
#include <string>
#include <utility>
#include <vector>

namespace cutload::calibtest {

using force_model::AxisMatrix;

// Seed 001, eq. 4.3: dynamometer axes to machine axes on the seed's set-up.
inline constexpr AxisMatrix kSeedAxes{0, -1, 0, -1, 0, 0, 0, 0, 1};

inline force_model::ToolSpec test_tool() {
    force_model::ToolSpec t;
    t.shape = force_model::ToolShape::Flat;
    t.diameter_mm = 8;
    t.flutes = 2;
    t.helix_deg = 30;
    t.flute_length_mm = 20;
    t.stickout_mm = 30;
    t.holder = {32, 40};
    return t;
}

// Coefficients of the order of an aluminium alloy, every term large enough to be identified.
inline force_model::Material true_material() { return {"truth", 800, 250, 150, 24, 30, 6}; }

enum class Side { Slot, Up, Down };

// A straight cut along +X through a box (10 mm long unless given) that leaves the immersion window open on one side;
// the tool starts and ends in air, so the record has idle time at both ends.
struct StraightCut {
    motion_io::MotionModel motion;
    force_model::RunSpec spec;
};

inline StraightCut straight_cut(double feed_per_tooth_mm, double axial_mm, Side side, double radial_mm,
                                double spindle_rpm = 10000, double step_s = 1e-3, double length = 10) {
    const force_model::ToolSpec tool = test_tool();
    const double R = tool.diameter_mm / 2, top_z = 5;
    StraightCut c;
    c.spec.tool = tool;
    c.spec.material = true_material();
    c.spec.resolution = {2.0, 0.1, 0.02};
    c.spec.stock.min_mm[0] = 0;
    c.spec.stock.max_mm[0] = length;
    c.spec.stock.min_mm[1] = side == Side::Up ? R - radial_mm : -R - 1;
    c.spec.stock.max_mm[1] = side == Side::Down ? -R + radial_mm : R + 1;
    c.spec.stock.max_mm[2] = top_z;
    const double feed_mm_min = feed_per_tooth_mm * tool.flutes * spindle_rpm, speed = feed_mm_min / 60;
    const double x0 = -R - 0.5, x1 = length + R + 0.5;
    auto& m = c.motion;
    m.step_s = step_s;
    m.block_names = {"N10"};
    m.session_start = {0};
    const auto n = static_cast<std::size_t>(std::ceil((x1 - x0) / speed / step_s)) + 1;
    for (std::size_t i = 0; i < n; ++i) {
        const double t = static_cast<double>(i) * step_s;
        m.t_s.push_back(t);
        m.x_mm.push_back(x0 + speed * t);
        m.y_mm.push_back(0);
        m.z_mm.push_back(top_z - axial_mm);
        m.vx_mm_s.push_back(speed);
        m.vy_mm_s.push_back(0);
        m.vz_mm_s.push_back(0);
        m.spindle_rpm.push_back(spindle_rpm);
        m.spindle_angle_deg.push_back(6.0 * spindle_rpm * t);
        m.block.push_back(0);
    }
    return c;
}

// Prediction-time span of straight_cut() in which the tool's whole engaged arc is inside the box, from
// the geometry alone: the centre at least margin_mm past the entry face, and the front of the tool
// at least margin_mm short of the exit face. (Every engaged point lies ahead of the centre, so the
// engagement is full from the centre's entry on, whatever the immersion.)
inline std::pair<double, double> full_engagement_span_s(double feed_per_tooth_mm, double spindle_rpm = 10000,
                                                        double length = 10, double margin_mm = 0.3) {
    const double R = test_tool().diameter_mm / 2, x0 = -R - 0.5;
    const double speed = feed_per_tooth_mm * test_tool().flutes * spindle_rpm / 60;
    return {(margin_mm - x0) / speed, (length - R - margin_mm - x0) / speed};
}

struct DynoOptions {
    double rate_Hz = 10000;
    double delay_s = 0.15123;          // measured time = prediction time + delay (idle lead-in)
    double tail_s = 0.03;              // idle recording after the prediction ends
    double runout = 0.04;              // flute j's force scaled by 1 + runout * (+1, -1, ...)
    double noise_rel = 0.02;           // noise standard deviation / peak resultant
    std::array<double, 3> zero_N{3.0, -2.0, 1.5};   // charge-amplifier offset at its reset, dynamometer axes
    AxisMatrix dyn_to_machine = kSeedAxes;
    int flutes = 2;
    unsigned seed = 11;
    // A part-only export: just the rows whose prediction time lies in [record_from_s, record_to_s]
    // are written (the steady part, say: no idle lead-in), with their acquisition time stamps.
    std::optional<double> record_from_s, record_to_s;
    // Charge-amplifier drift, linear from the reset at acquisition time 0: each channel drifts over
    // the written record by drift_rel[ch] times the magnitude of the record's mean cutting force.
    std::array<double, 3> drift_rel{0, 0, 0};
    // The converter's step (a 16-bit converter over +-range: range / 32768); 0: none.
    double quantum_N = 0;
};

// What write_dyno_file wrote, for the tests to check against (dynamometer channels).
struct DynoRecord {
    double t_first_s = 0, t_last_s = 0;          // record time of the first and last rows
    std::size_t rows = 0;
    double mean_cut_N = 0;                       // magnitude of the mean cutting force over the record
    std::array<double, 3> drift_N_per_s{};
    std::array<double, 3> offset_at(double t_record_s, const DynoOptions& o) const {
        return {o.zero_N[0] + drift_N_per_s[0] * t_record_s, o.zero_N[1] + drift_N_per_s[1] * t_record_s,
                o.zero_N[2] + drift_N_per_s[2] * t_record_s};
    }
};

inline std::array<double, 9> inverse(const AxisMatrix& a) {
    const double det = a[0] * (a[4] * a[8] - a[5] * a[7]) - a[1] * (a[3] * a[8] - a[5] * a[6]) +
                       a[2] * (a[3] * a[7] - a[4] * a[6]);
    return {(a[4] * a[8] - a[5] * a[7]) / det, (a[2] * a[7] - a[1] * a[8]) / det, (a[1] * a[5] - a[2] * a[4]) / det,
            (a[5] * a[6] - a[3] * a[8]) / det, (a[0] * a[8] - a[2] * a[6]) / det, (a[2] * a[3] - a[0] * a[5]) / det,
            (a[3] * a[7] - a[4] * a[6]) / det, (a[1] * a[6] - a[0] * a[7]) / det, (a[0] * a[4] - a[1] * a[3]) / det};
}

// Writes the record as a DynoWare-style export (metadata, names, units, Fx Fy Fz Mz).
inline DynoRecord write_dyno_file(const force_model::Prediction& p, const std::string& path, const DynoOptions& o) {
    const auto& s = p.samples;
    double peak = 0;
    for (const auto& r : s) peak = std::max(peak, std::hypot(double(r.fx_N), double(r.fy_N), double(r.fz_N)));
    std::mt19937 rng(o.seed);
    // Box-Muller on the raw engine output: std distributions differ between standard libraries.
    auto gauss = [&] {
        const double u1 = (static_cast<double>(rng()) + 1.0) / 4294967297.0;
        const double u2 = static_cast<double>(rng()) / 4294967296.0;
        return std::sqrt(-2 * std::log(u1)) * std::cos(2 * std::numbers::pi * u2);
    };
    const auto inv = inverse(o.dyn_to_machine);
    // Rows i0..i1 of the acquisition (time i / rate) are written.
    const double t_end = s.back().t_s + o.delay_s + o.tail_s;
    auto row_at = [&](double t_pred) { return t_pred + o.delay_s; };
    const auto i0 = static_cast<std::size_t>(o.record_from_s ? std::ceil(row_at(*o.record_from_s) * o.rate_Hz) : 0.0);
    const auto i1 = static_cast<std::size_t>(std::floor((o.record_to_s ? row_at(*o.record_to_s) : t_end) * o.rate_Hz));
    // The force on the workpiece in dynamometer axes at acquisition time tm, runout included.
    std::size_t j = 0;
    auto force_dyn = [&](double tm) {
        const double tp = tm - o.delay_s;
        double f[3] = {0, 0, 0};
        if (tp >= s.front().t_s && tp <= s.back().t_s) {
            while (j + 2 < s.size() && s[j + 1].t_s <= tp) ++j;
            const auto& a = s[j];
            const auto& b = s[j + 1];
            const double u = b.t_s > a.t_s ? (tp - a.t_s) / (b.t_s - a.t_s) : 0.0;
            const double angle = a.spindle_angle_deg + u * (b.spindle_angle_deg - a.spindle_angle_deg);
            const auto flute = static_cast<long>(std::floor(angle / (360.0 / o.flutes)));
            const double scale = 1 + o.runout * (flute % 2 == 0 ? 1.0 : -1.0);
            f[0] = scale * (a.fx_N + u * (b.fx_N - a.fx_N));
            f[1] = scale * (a.fy_N + u * (b.fy_N - a.fy_N));
            f[2] = scale * (a.fz_N + u * (b.fz_N - a.fz_N));
        }
        std::array<double, 3> d{};
        // On the workpiece, in dynamometer axes: F_dyn = A^-1 (-F_tool).
        for (int r = 0; r < 3; ++r) d[r] = -(inv[3 * r] * f[0] + inv[3 * r + 1] * f[1] + inv[3 * r + 2] * f[2]);
        return d;
    };
    DynoRecord rec;
    rec.t_first_s = static_cast<double>(i0) / o.rate_Hz;
    rec.t_last_s = static_cast<double>(i1) / o.rate_Hz;
    rec.rows = i1 + 1 - i0;
    std::array<double, 3> sum{};
    for (std::size_t i = i0; i <= i1; ++i) {
        const auto d = force_dyn(static_cast<double>(i) / o.rate_Hz);
        for (int r = 0; r < 3; ++r) sum[r] += d[r];
    }
    rec.mean_cut_N = std::hypot(sum[0], sum[1], sum[2]) / static_cast<double>(rec.rows);
    for (int r = 0; r < 3; ++r)
        rec.drift_N_per_s[r] = o.drift_rel[r] * rec.mean_cut_N / std::max(rec.t_last_s - rec.t_first_s, 1e-9);

    std::ofstream out(path);
    out << "DynoWare,Version 3.2.2.0\nMeasurement:,calibration test\nSampling rate [Hz]:,"
        << o.rate_Hz << "\nNumber of samples:,unknown\n\nTime,Fx,Fy,Fz,Mz\ns,N,N,N,N*cm\n";
    char line[160];
    j = 0;
    for (std::size_t i = i0; i <= i1; ++i) {
        const double tm = static_cast<double>(i) / o.rate_Hz;
        const auto f = force_dyn(tm);
        const auto offset = rec.offset_at(tm, o);
        double d[3];
        for (int r = 0; r < 3; ++r) {
            d[r] = f[r] + offset[r] + o.noise_rel * peak * gauss();
            if (o.quantum_N > 0) d[r] = o.quantum_N * std::round(d[r] / o.quantum_N);
        }
        std::snprintf(line, sizeof line, "%.6f,%.4f,%.4f,%.4f,%.3f\n", tm, d[0], d[1], d[2], 0.1 * gauss());
        out << line;
    }
    return rec;
}

}  // namespace cutload::calibtest
