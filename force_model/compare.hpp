// Prediction against measurement: time alignment by cross-correlation, zero-phase low-pass,
// per-tooth / per-revolution averaging and error metrics per axis, overall and per NC block.
//
// Both traces are compared on the measurement's sampling grid, as forces on the tool in the axes of
// the prediction's fx_N, fy_N, fz_N: workpiece (stock) axes as predicted, which are the machine
// axes on a three-axis machine (app::CompareSettings::frame picks the machine-axis columns of a
// five-axis run instead). Offsets follow one convention everywhere: prediction time = measured
// time + offset_s.
#pragma once

#include "force_model/force_model.hpp"
#include "force_model/measurement.hpp"
#include "force_model/zero_drift.hpp"

#include <nlohmann/json_fwd.hpp>

#include <array>
#include <istream>
#include <optional>
#include <string>
#include <vector>

namespace cutload::force_model {

// The rows compare() needs from a prediction (all of Prediction::samples, or FORCES.csv read back).
struct PredictedTrace {
    std::vector<ForceSample> samples;   // sorted by time
    std::vector<std::string> block_names;
    // The file it was read from, as messages show it (textio::printable); empty for a prediction
    // in memory.
    std::string source;
    // True when the file held fx_machine_N, fy_machine_N and fz_machine_N (predicted with a
    // machine definition), read into ForceSample::fx_machine_N ...; false for a prediction in
    // memory, whose machine-axis forces only the application knows to be filled.
    bool machine_axes = false;
};

PredictedTrace predicted_trace(const Prediction& p);
// Reads FORCES.csv as written by write_forces_csv (columns t_s, spindle_angle_deg, block, fx_N, fy_N,
// fz_N at least, and fx_machine_N, fy_machine_N, fz_machine_N where all three are there); throws
// MeasurementError naming line and column.
PredictedTrace read_forces_csv(const std::string& path);
PredictedTrace read_forces_csv(std::istream& in, const std::string& source);
// Reads FORCES.bin (docs/formats.md): every column it knows, so the rows equal FORCES.csv's read
// back; throws MeasurementError naming the byte offset and what is wrong there.
PredictedTrace read_forces_bin(std::istream& in, const std::string& source);
// FORCES.csv or FORCES.bin, told apart by the first byte (so a pipe works too).
PredictedTrace read_predicted_forces(const std::string& path);

// Zero-phase low-pass: a Butterworth filter run forward and backward (squared magnitude response,
// no phase shift), with odd-reflection padding at both ends. cutoff_Hz must be below rate_Hz / 2.
void lowpass_zero_phase(std::vector<float>& x, double rate_Hz, double cutoff_Hz, int order = 4);

enum class Averaging { None, ToothPeriod, Revolution };
const char* averaging_name(Averaging a);

struct CompareOptions {
    std::optional<double> offset_s;              // empty: found by cross-correlation
    double t_start_s = -1e300, t_end_s = 1e300;  // window in prediction time
    // Default cut-off: below the first resonance of common table dynamometers (a few kHz) and above
    // the first harmonics of the tooth-passing frequency of typical aluminium cuts. 0: no filter.
    double cutoff_Hz = 1000;
    Averaging averaging = Averaging::None;
    int flutes = 0;   // needed for Averaging::ToothPeriod
    // Subtract the dynamometer's zero offset, found from the samples where the prediction is exactly
    // zero (the tool in air: before and after the cut, and between tooth passes in partial
    // immersion) and 2 samples clear of any where it is not. Needs at least 100 such samples, else
    // nothing is removed. Where they spread over at least half the compared span and their slope
    // stands out from the noise (drift_significant), the zero is a least-squares line through them
    // (the amplifier's drift), else their mean.
    bool remove_zero = true;
    // The zero offset at the record's first sample (tool, compared axes), instead of the one found;
    // the drift is still taken from the air samples where they allow.
    std::optional<std::array<double, 3>> zero_N;
};

// Metrics of predicted minus measured. nrmse = rmse / measured peak-to-peak; peak_error_N =
// max |predicted| - max |measured|; correlation is Pearson's r (NaN when a signal is constant).
struct AxisMetrics {
    double mean_error_N = 0, rmse_N = 0, nrmse = 0, peak_error_N = 0, correlation = 0;
    double peak_measured_N = 0, peak_predicted_N = 0;
};

// axes[0..2] = x, y, z; axes[3] = resultant |F|.
struct ScopeMetrics {
    std::string scope;   // "overall" or a block name
    double t_start_s = 0, t_end_s = 0;
    std::size_t samples = 0;
    AxisMetrics axes[4];
};

struct Comparison {
    double offset_s = 0;
    bool offset_found = false;         // true: by cross-correlation; false: given
    double alignment_score = 0;        // Pearson correlation over the overlap at the found offset
    double rate_Hz = 0, cutoff_Hz = 0;
    Averaging averaging = Averaging::None;
    bool zero_removed = false;
    // The zero offset removed (tool, compared axes) at zero.t_s: the mean time of the air samples, or
    // the record's first sample when given; zero.at(t) over time (prediction time), with its source
    // and drift.
    double zero_N[3] = {0, 0, 0};
    ZeroLine zero;
    ScopeMetrics overall;
    std::vector<ScopeMetrics> blocks;
    // The compared series (after filtering and averaging), for plots: prediction time.
    std::vector<double> t_s;
    std::vector<float> predicted[3], measured[3];
    std::vector<std::int32_t> block;
};

// The measurement must already be mapped to force on the tool in the prediction's axes
// (map_to_tool_machine_axes, whose name dates from three-axis machines).
// Throws MeasurementError when the window or the overlap is empty.
Comparison compare(const PredictedTrace& predicted, const Measurement& measured, const CompareOptions& opt);

// Offset (prediction time = measured time + offset) maximising the Pearson correlation of the three
// axes over their overlap: a coarse search over every lag on anti-aliased signals at about 2 kHz
// (FFT), then a full-rate search around every coarse peak within 0.05 of the best (at most 64; the
// cost is about 3 n (2 f + 1) per peak for n samples decimated by f) with parabolic sub-sample
// refinement. score: that correlation at the offset found.
double find_offset_s(const PredictedTrace& predicted, const Measurement& measured, double* score = nullptr);

// The report without the series: offset, settings, overall and per-block metrics.
nlohmann::json to_json(const Comparison& c);
// One row per scope and axis: scope,axis,samples,t_start_s,t_end_s,mean_error_N,rmse_N,nrmse,
// peak_error_N,peak_measured_N,peak_predicted_N,correlation.
void write_comparison_csv(const Comparison& c, const std::string& path);
// The compared series: t_s,block,fx_pred_N,fy_pred_N,fz_pred_N,fx_meas_N,fy_meas_N,fz_meas_N.
void write_comparison_trace_csv(const Comparison& c, const std::vector<std::string>& block_names,
                                const std::string& path);

}  // namespace cutload::force_model
