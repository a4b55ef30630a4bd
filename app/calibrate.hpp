// Use case: identify cutting coefficients. Straight dynamometer tests of a tool (each a record and
// its cutting conditions) give their steady mean forces; the six coefficients Ktc, Krc, Kac, Kte,
// Kre, Kae are fitted to them by least squares (docs/compare_calibrate.md).
#pragma once

#include "app/control.hpp"
#include "force_model/calibrate.hpp"
#include "force_model/force_model.hpp"
#include "force_model/measurement.hpp"

#include <array>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace cutload::app {

enum class RegressorModel {
    Engine,       // the engine predicts each test with unit coefficients: any tool shape
    ClosedForm,   // average forces of a flat end mill in closed form
};

struct CalibrationTest {
    std::string file;                     // the record: read from this file unless `content` is given; names it in errors
    std::optional<std::string> content;   // the record itself (an upload)
    force_model::CutTest test;
    std::optional<double> from_s, to_s;                // steady window in the record's time (default: detected)
    std::optional<std::array<double, 3>> zero_dyn_N;   // reading with no load at the record's start, its own
                                                       // channels (default: lead-in, idle tail or estimated)
};

struct CalibrationInput {
    force_model::ToolSpec tool;
    std::vector<CalibrationTest> tests;
    force_model::AxisMatrix axes = force_model::kIdentityAxes;
    bool measured_on_workpiece = true;
    RegressorModel model = RegressorModel::Engine;
    force_model::Device device = force_model::Device::Cpu;   // of the engine regressors
    std::string material_name = "calibrated";
};

struct CalibratedTest {
    force_model::SteadyForce steady;            // steady window and mean force, machine axes
    std::array<double, 3> mean_feed_frame_N{};  // the same mean in the feed frame: what is fitted
};

struct Calibration {
    std::vector<CalibratedTest> tests;   // in the input's order
    force_model::CalibrationFit fit;     // the material, residuals, condition number
};

// A test's record needs its steady window or its zero given (`need`); `file` names the test, as
// its conditions do.
class SteadyInputNeeded : public force_model::SteadyError {
public:
    SteadyInputNeeded(const force_model::SteadyError& e, std::string file) : SteadyError(e.what(), e.need), file(std::move(file)) {}
    std::string file;
};

// Phase Calibrate: every record is read first (a bad one fails before any engine time), then the
// regressors, one test after the other; Done. Throws force_model::MeasurementError for a bad
// record, SteadyInputNeeded when a record needs a window or a zero given (its `need` says which), force_model::SpecError for a test the tool cannot cut or tests that cannot determine all
// six coefficients, force_model::Cancelled.
Calibration calibrate(const CalibrationInput& input, const Control& control = {});

}  // namespace cutload::app
