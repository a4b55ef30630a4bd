#include "app/compare.hpp"

#include <utility>

namespace cutload::app {

MeasurementComparison compare_measurement(const force_model::PredictedTrace& predicted, force_model::Measurement measured,
                                          const CompareSettings& settings) {
    MeasurementComparison r{std::move(measured), {}};
    force_model::map_to_tool_machine_axes(r.measured, settings.axes, settings.measured_on_workpiece);
    force_model::CompareOptions options = settings.options;
    if (settings.zero_dyn_N)
        options.zero_N = force_model::to_tool_machine_axes(*settings.zero_dyn_N, settings.axes, settings.measured_on_workpiece);
    r.comparison = force_model::compare(predicted, r.measured, options);
    return r;
}

MeasurementComparison compare_measurement(const force_model::PredictedTrace& predicted, const std::string& measured_path,
                                          const CompareSettings& settings) {
    return compare_measurement(predicted, force_model::read_measurement(measured_path), settings);
}

MeasurementComparison compare_measurement(const force_model::PredictedTrace& predicted, std::istream& measured,
                                          const std::string& measured_name, const CompareSettings& settings) {
    return compare_measurement(predicted, force_model::read_measurement(measured, measured_name), settings);
}

}  // namespace cutload::app
