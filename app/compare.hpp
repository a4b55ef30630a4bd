// Use case: compare a prediction with a dynamometer measurement. The record is mapped to force
// on the tool in machine axes, aligned in time and filtered, and the error metrics are taken per
// axis, overall and per NC block.
#pragma once

#include "force_model/compare.hpp"
#include "force_model/force_model.hpp"
#include "force_model/measurement.hpp"

#include <array>
#include <istream>
#include <optional>
#include <string>

namespace cutload::app {

struct CompareSettings {
    force_model::AxisMatrix axes = force_model::kIdentityAxes;   // dynamometer axes to machine axes
    bool measured_on_workpiece = true;                           // the dynamometer carries the workpiece
    std::optional<std::array<double, 3>> zero_dyn_N;             // zero offset given in the record's own channels
                                                                 // (overrides options.zero_N once mapped)
    force_model::CompareOptions options;                         // offset, window, filter, averaging, zero
};

struct MeasurementComparison {
    force_model::Measurement measured;      // in tool / machine axes
    force_model::Comparison comparison;
};

// force_model::MeasurementError naming file, line and column for a bad record, or saying why the
// window or the overlap is empty.
MeasurementComparison compare_measurement(const force_model::PredictedTrace& predicted, force_model::Measurement measured,
                                          const CompareSettings& settings);
MeasurementComparison compare_measurement(const force_model::PredictedTrace& predicted, const std::string& measured_path,
                                          const CompareSettings& settings);
MeasurementComparison compare_measurement(const force_model::PredictedTrace& predicted, std::istream& measured,
                                          const std::string& measured_name, const CompareSettings& settings);

}  // namespace cutload::app
