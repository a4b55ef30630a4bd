#include "app/calibrate.hpp"

#include "tracker.hpp"

#include <sstream>

namespace cutload::app {
namespace {

Calibration calibrate_steps(const CalibrationInput& in, const Control& control) {
    Tracker track(control);
    track.begin(Phase::Calibrate, 0, 1);
    Calibration out;
    std::vector<std::array<double, 3>> means;
    for (const CalibrationTest& t : in.tests) {
        try {
            force_model::validate_cut_test(t.test, in.tool);
        } catch (const force_model::SpecError& e) {
            throw force_model::SpecError(t.file + ": " + e.what());
        }
        force_model::Measurement m;
        if (t.content) {
            std::istringstream text(*t.content);
            m = force_model::read_measurement(text, t.file);
        } else {
            m = force_model::read_measurement(t.file);
        }
        force_model::map_to_tool_machine_axes(m, in.axes, in.measured_on_workpiece);
        force_model::SteadyOptions steady;
        steady.t_start_s = t.from_s;
        steady.t_end_s = t.to_s;
        if (t.zero_dyn_N) steady.zero_N = force_model::to_tool_machine_axes(*t.zero_dyn_N, in.axes, in.measured_on_workpiece);
        // The tooth-passing pattern the detector and the zero estimate look for.
        steady.flutes = in.tool.flutes;
        steady.air_fraction = force_model::tooth_air_fraction(in.tool, t.test);
        CalibratedTest c;
        try {
            c.steady = force_model::steady_mean_force(m, t.test.spindle_rpm, steady);
        } catch (const force_model::SteadyError& e) {
            throw SteadyInputNeeded(e, t.file);
        }
        c.mean_feed_frame_N = force_model::to_feed_frame(c.steady.mean_N, t.test.feed_direction_deg);
        means.push_back(c.mean_feed_frame_N);
        out.tests.push_back(c);
        track.check();
    }
    force_model::EngineRegressorOptions engine;
    engine.device = in.device;
    std::vector<force_model::Regressors> regs;
    for (const CalibrationTest& t : in.tests) {
        regs.push_back(in.model == RegressorModel::ClosedForm ? force_model::closed_form_regressors(in.tool, t.test)
                                                              : force_model::engine_regressors(in.tool, t.test, engine));
        track.check();
        track.report(double(regs.size()) / double(in.tests.size()));
    }
    out.fit = force_model::fit_mean_forces(regs, means, in.material_name);
    track.done();
    return out;
}

}  // namespace

Calibration calibrate(const CalibrationInput& in, const Control& control) {
    return cancellable(control, [&] { return calibrate_steps(in, control); });
}

}  // namespace cutload::app
