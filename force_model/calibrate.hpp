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

// Closed-form average over a tooth period for a flat end mill; throws SpecError for other shapes.
Regressors closed_form_regressors(const ToolSpec& tool, const CutTest& test);

// The engine's mean over whole revolutions of a synthetic steady cut (six predictions).
struct EngineRegressorOptions {
    Resolution resolution{1.0, 0.05, 0.02};
    Device device = Device::Cpu;
    int revolutions = 10;   // steady revolutions averaged
};
Regressors engine_regressors(const ToolSpec& tool, const CutTest& test, const EngineRegressorOptions& opt = {});

// Steady segment of a measured straight cut (measurement already in tool / machine axes).
// Revolution means are formed from the spindle speed; the zero offset is the mean of the
// revolutions before the cut; cutting revolutions exceed `threshold` of the largest mean force;
// the steady segment is the longest run of cutting revolutions whose 5-revolution moving mean stays
// within `tolerance` of their median, less two revolutions at each end. The tolerance is tight
// because an entry ramp ends flat: at 5 % ramp revolutions got in and biased slot means by 2.5 %.
struct SteadyOptions {
    double threshold = 0.5;
    double tolerance = 0.02;
    int min_revolutions = 3;
    std::optional<double> t_start_s, t_end_s;   // explicit steady window (file time): no detection
};
struct SteadyForce {
    double t_start_s = 0, t_end_s = 0;
    int revolutions = 0;
    std::array<double, 3> mean_N{};   // machine axes, zero offset removed
    std::array<double, 3> zero_N{};   // the zero offset removed (0 when the cut starts the record)
    bool zeroed = false;
};
SteadyForce steady_mean_force(const Measurement& mapped, double spindle_rpm, const SteadyOptions& opt = {});

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
