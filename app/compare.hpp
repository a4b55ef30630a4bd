// Use case: compare a prediction with a dynamometer measurement. The record is mapped to force
// on the tool in the compared frame's axes (workpiece axes, or machine axes for a five-axis run
// predicted with a machine definition), aligned in time and filtered, and the error metrics are
// taken per axis, overall and per NC block.
#pragma once

#include "force_model/compare.hpp"
#include "force_model/force_model.hpp"
#include "force_model/measurement.hpp"

#include <array>
#include <istream>
#include <optional>
#include <string>

namespace cutload::app {

// The axes the dynamometer measures in, and so which predicted triplet it is compared with.
// Workpiece: fx_N, fy_N, fz_N (the workpiece's (stock) axes; on a three-axis machine these are
// the machine axes): a dynamometer under the part on a rotary table turns with it. Machine:
// fx_machine_N, fy_machine_N, fz_machine_N of a run predicted with --machine: a dynamometer fixed
// to the bed (or on the spindle side) does not turn with the part.
enum class ForceFrame { Workpiece, Machine };
const char* force_frame_name(ForceFrame f);   // "workpiece" or "machine"

struct CompareSettings {
    force_model::AxisMatrix axes = force_model::kIdentityAxes;   // dynamometer axes to the frame's axes
    bool measured_on_workpiece = true;                           // the dynamometer carries the workpiece
    ForceFrame frame = ForceFrame::Workpiece;
    std::optional<std::array<double, 3>> zero_dyn_N;             // zero offset given in the record's own channels
                                                                 // (overrides options.zero_N once mapped)
    force_model::CompareOptions options;                         // offset, window, filter, averaging, zero
};

struct MeasurementComparison {
    force_model::Measurement measured;      // force on the tool, in the frame's axes
    force_model::Comparison comparison;
};

// force_model::MeasurementError naming file, line and column for a bad record, or saying why the
// window or the overlap is empty. With ForceFrame::Machine, a prediction without the machine-axis
// columns (predicted.machine_axes false) is refused first, naming predicted.source.
MeasurementComparison compare_measurement(const force_model::PredictedTrace& predicted, force_model::Measurement measured,
                                          const CompareSettings& settings);
MeasurementComparison compare_measurement(const force_model::PredictedTrace& predicted, const std::string& measured_path,
                                          const CompareSettings& settings);
MeasurementComparison compare_measurement(const force_model::PredictedTrace& predicted, std::istream& measured,
                                          const std::string& measured_name, const CompareSettings& settings);

}  // namespace cutload::app
