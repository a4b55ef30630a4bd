#include "app/predict_run.hpp"

#include "tracker.hpp"

#include <algorithm>

namespace cutload::app {
namespace {

RunResult predict_steps(const RunInput& in, const Control& control) {
    Tracker track(control);
    RunResult r;
    track.begin(Phase::Ingest, 0, 0);
    r.motion = motion_io::ingest(in.log_path, in.read, &r.ingest);
    if (r.motion.size() < 2) throw motion_io::IngestError(in.log_path + ": the log holds fewer than two motion samples");

    // Before predicting: a log without the program's block names takes them by mapping.
    if (in.program) {
        track.begin(Phase::Program, 0, 0);
        motion_io::NcProgram program = read_program(*in.program, in.spec, log_start_mm(r.motion));
        track.begin(Phase::Mapping, 0, 0);
        r.program = prepare_program_run(std::move(program), in.program->settings, r.motion);
    }

    // The commanded prediction follows the actual one; they share the progress by duration.
    double actual_share = 1;
    if (r.program) {
        double commanded_s = 0;
        for (double d : motion_io::commanded_durations_s(r.program->program, r.program->commanded)) commanded_s += d;
        const double actual_s = r.motion.t_s.back() - r.motion.t_s.front();
        actual_share = actual_s / std::max(1e-9, actual_s + commanded_s);
    }
    force_model::PredictOptions po;
    po.device = in.device;
    po.base_stock = in.base_stock;
    po.cancel = control.cancel;
    track.begin(Phase::Predict, 0, actual_share);
    po.progress = track.engine_progress();
    r.prediction = force_model::predict(r.motion, in.spec, po);
    if (r.program) {
        track.begin(Phase::Commanded, actual_share, 1);
        po.progress = track.engine_progress();
        r.commanded = predict_program(*r.program, r.motion, r.prediction, in.spec, po);
    }
    track.done();
    return r;
}

}  // namespace

RunResult predict_run(const RunInput& in, const Control& control) {
    return cancellable(control, [&] { return predict_steps(in, control); });
}

}  // namespace cutload::app
