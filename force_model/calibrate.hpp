// Cutting-coefficient identification from dynamometer tests (Altintas, Manufacturing Automation,
// 2nd ed., 2012, ch. 2): forces are linear in Ktc, Krc, Kac, Kte, Kre, Kae, so mean forces of steady
// cuts (or period means of any measured run) determine them by linear least squares.
//
// The regressors (mean force per unit coefficient) come either from the closed-form average forces
// of a flat end mill or from the engine itself, predicting the same cut with one coefficient set to 1
// and the others to 0 — the latter works for every tool shape and matches what predict() will do.
#pragma once

#include "force_model/compare.hpp"
#include "force_model/force_model.hpp"
#include "force_model/measurement.hpp"
#include "force_model/zero_drift.hpp"

#include <nlohmann/json_fwd.hpp>

#include <array>
#include <optional>
#include <string>
#include <vector>

namespace cutload::force_model {

enum class Immersion { Slot, Up, Down };
Immersion parse_immersion(const std::string& text);   // slot | up | down; throws SpecError
const char* immersion_name(Immersion m);

// A straight cut at constant feed and spindle speed, steady in its middle.
struct CutTest {
    double spindle_rpm = 0, feed_mm_min = 0, axial_mm = 0, radial_mm = 0;
    Immersion mode = Immersion::Slot;     // slot ignores radial_mm (the full diameter cuts)
    double feed_direction_deg = 0;        // machine XY plane, counter-clockwise from +X
};

// Throws SpecError naming the bad field (speed, feed, depths against the tool).
void validate_cut_test(const CutTest& t, const ToolSpec& tool);

// Coefficient order everywhere: Ktc, Krc, Kac, Kte, Kre, Kae.
inline constexpr const char* kCoefficientKeys[6] = {"Ktc_N_mm2", "Krc_N_mm2", "Kac_N_mm2",
                                                    "Kte_N_mm",  "Kre_N_mm",  "Kae_N_mm"};
std::array<double, 6> coefficients_of(const Material& m);
Material material_of(const std::array<double, 6>& k, const std::string& name);

// Mean force on the tool in the feed frame (x along the feed, y to its left, z up) per unit
// coefficient: r[axis][k].
using Regressors = std::array<std::array<double, 6>, 3>;

// Closed-form average over a tooth period for an untapered flat end mill; throws SpecError for
// other shapes and for tapers.
Regressors closed_form_regressors(const ToolSpec& tool, const CutTest& test);

// The engine's mean over whole revolutions of a synthetic steady cut (six predictions).
struct EngineRegressorOptions {
    Resolution resolution{1.0, 0.05, 0.02};
    Device device = Device::Cpu;
    int revolutions = 10;   // steady revolutions averaged
};
Regressors engine_regressors(const ToolSpec& tool, const CutTest& test, const EngineRegressorOptions& opt = {});

// Steady segment of a measured straight cut (measurement already in tool / machine axes) and its
// mean force less the dynamometer's zero offset. Real records are often the steady part only (no
// idle lead-in) and drift by a few newtons, so the detector (docs/compare_calibrate.md) works on
// revolution means and on each revolution's tooth-passing ripple, which neither the offset nor the
// drift touches:
// - idle revolutions are those without ripple; those at the start are the lead-in, those at the end
//   the idle tail; cutting revolutions have at least `threshold` of the typical (90th percentile)
//   ripple;
// - the drift is the line through the lead-in and the tail when both exist, else the trend of the
//   steady revolution means, taken only where it stands out from the noise (drift_significant);
// - the steady segment is the longest run of cutting revolutions whose 5-revolution moving mean,
//   drift removed, stays within `tolerance` of their median, less two revolutions at each end. The
//   tolerance is tight because an entry ramp ends flat: at 5 % ramp revolutions got in and biased
//   slot means by 2.5 %;
// - the zero offset at the window's centre is, in this order: given, from the lead-in, from the
//   idle tail (each carried along the drift), or estimated from the air between tooth passes when
//   the cut has some (`tooth_air_fraction`); with none of these the record is refused.
enum class SteadyDetector {
    Robust,
    // The first detector, kept to show what it cannot do: cut levels relative to the first
    // revolution (which must be idle), no drift, zero offset from the lead-in or none.
    FirstRevolution,
};
struct SteadyOptions {
    double threshold = 0.5;
    double tolerance = 0.02;
    int min_revolutions = 3;
    std::optional<double> t_start_s, t_end_s;   // explicit steady window (file time): no detection
    // The zero offset at the record's first sample (tool / machine axes); the drift found is added
    // from there. Empty: found in the record.
    std::optional<std::array<double, 3>> zero_N;
    // For the estimate from the air between tooth passes: the number of flutes and the share of each
    // tooth period in which no edge cuts (tooth_air_fraction). 0: no estimate.
    int flutes = 0;
    double air_fraction = 0;
    SteadyDetector detector = SteadyDetector::Robust;
};
struct SteadyForce {
    double t_start_s = 0, t_end_s = 0;
    int revolutions = 0;
    bool window_given = false;
    std::array<double, 3> mean_N{};   // machine axes, zero offset removed
    std::array<double, 3> zero_N{};   // the zero offset removed: its value at the window's centre
    bool zeroed = false;
    ZeroLine zero;                    // the zero offset over time, where it came from, the drift
    std::array<double, 3> drift_N() const {   // drift over the window
        const double span = t_end_s - t_start_s;
        return {zero.drift_N_per_s[0] * span, zero.drift_N_per_s[1] * span, zero.drift_N_per_s[2] * span};
    }
};

// A record whose steady window or zero offset cannot be found; `need` says what to give instead
// (each front end names its own way of giving it).
class SteadyError : public MeasurementError {
public:
    enum class Need { Window, Zero };
    SteadyError(const std::string& what, Need need) : MeasurementError(what), need(need) {}
    Need need;
};

SteadyForce steady_mean_force(const Measurement& mapped, double spindle_rpm, const SteadyOptions& opt = {});

// Share of each tooth period in which no edge of a flat end mill cuts in this test: one less the
// immersion angle and the helix lag over the depth (a tan(helix) / R), over the tooth pitch. 0 for a
// slot, for other tool shapes and tapers (whose lag this formula does not give) and when the edges
// overlap.
double tooth_air_fraction(const ToolSpec& tool, const CutTest& test);

std::array<double, 3> to_feed_frame(const std::array<double, 3>& machine_N, double feed_direction_deg);

struct CalibrationFit {
    Material material;
    std::size_t equations = 0;
    double rms_residual_N = 0;
    double relative_rms_residual = 0;   // rms residual / rms of the fitted data
    // Largest over smallest singular value of the regressor matrix with unit-norm columns: how
    // well the tests separate the six coefficients (1 is ideal; above ~1e4 some are guesses).
    double condition_number = 0;
    std::vector<double> group_rms_residual_N;   // per test or run
};

// Least squares over the tests' steady mean forces (feed frame). Throws SpecError when the tests
// cannot determine all six coefficients.
CalibrationFit fit_mean_forces(const std::vector<Regressors>& regressors,
                               const std::vector<std::array<double, 3>>& mean_force_feed_N, const std::string& name);

// General route: measured runs along any path. Each run is predicted six times with unit
// coefficients; the period means (per revolution) of those predictions are the regressors of the
// measured period means. Periods where the prediction is in air set the measured zero offset.
struct MeasuredRun {
    const motion_io::MotionModel* motion = nullptr;
    RunSpec spec;                       // tool, stock, setup, resolution (material: used only to align)
    const Measurement* measured = nullptr;   // tool / machine axes
    std::optional<double> offset_s;     // empty: aligned by cross-correlation
};
struct RunCalibrationOptions {
    Device device = Device::Cpu;
    double cutoff_Hz = 1000;
};
CalibrationFit calibrate_from_runs(const std::vector<MeasuredRun>& runs, const RunCalibrationOptions& opt,
                                   const std::string& name);

// The run spec's `material` object.
nlohmann::json material_json(const Material& m);

}  // namespace cutload::force_model
