#include "app/compare.hpp"

#include <utility>

namespace cutload::app {

namespace {

// Before the record is read: a refused frame is the cheaper and the more useful message.
void require_frame(const force_model::PredictedTrace& predicted, const CompareSettings& settings) {
    if (settings.frame == ForceFrame::Machine && !predicted.machine_axes)
        throw force_model::MeasurementError(
            (predicted.source.empty() ? std::string("the prediction") : predicted.source) +
            ": no fx_machine_N, fy_machine_N, fz_machine_N columns: it was predicted without --machine, so it has no "
            "forces in machine axes to compare (--frame machine)");
}

// compare() reads fx_N, fy_N, fz_N: a copy with the machine-axis forces there. Only the machine
// frame pays for it; the workpiece frame compares the trace as given.
force_model::PredictedTrace in_machine_axes(const force_model::PredictedTrace& predicted) {
    force_model::PredictedTrace t = predicted;
    for (force_model::ForceSample& s : t.samples) {
        s.fx_N = s.fx_machine_N;
        s.fy_N = s.fy_machine_N;
        s.fz_N = s.fz_machine_N;
    }
    return t;
}

}  // namespace

const char* force_frame_name(ForceFrame f) { return f == ForceFrame::Machine ? "machine" : "workpiece"; }

MeasurementComparison compare_measurement(const force_model::PredictedTrace& predicted, force_model::Measurement measured,
                                          const CompareSettings& settings) {
    require_frame(predicted, settings);
    MeasurementComparison r{std::move(measured), {}};
    force_model::map_to_tool_machine_axes(r.measured, settings.axes, settings.measured_on_workpiece);
    force_model::CompareOptions options = settings.options;
    if (settings.zero_dyn_N)
        options.zero_N = force_model::to_tool_machine_axes(*settings.zero_dyn_N, settings.axes, settings.measured_on_workpiece);
    r.comparison = settings.frame == ForceFrame::Machine ? force_model::compare(in_machine_axes(predicted), r.measured, options)
                                                         : force_model::compare(predicted, r.measured, options);
    return r;
}

MeasurementComparison compare_measurement(const force_model::PredictedTrace& predicted, const std::string& measured_path,
                                          const CompareSettings& settings) {
    require_frame(predicted, settings);
    return compare_measurement(predicted, force_model::read_measurement(measured_path), settings);
}

MeasurementComparison compare_measurement(const force_model::PredictedTrace& predicted, std::istream& measured,
                                          const std::string& measured_name, const CompareSettings& settings) {
    require_frame(predicted, settings);
    return compare_measurement(predicted, force_model::read_measurement(measured, measured_name), settings);
}

}  // namespace cutload::app
