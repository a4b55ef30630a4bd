#include "app/optimize.hpp"

#include "tracker.hpp"

#include <algorithm>

namespace cutload::app {
namespace {

OptimizeResult optimize_steps(const OptimizeInput& in, const Control& control) {
    Tracker track(control);
    OptimizeResult r;
    track.begin(Phase::Ingest, 0, 0);
    r.motion = motion_io::ingest(in.log_path, in.read);
    if (r.motion.size() < 2) throw motion_io::IngestError(in.log_path + ": the log holds fewer than two motion samples");
    track.begin(Phase::Program, 0, 0);
    ProgramSource source = in.program;
    source.settings.limits.sample_step_s = r.motion.step_s;   // the commanded samples it may imply
    motion_io::NcProgram program = read_program(source, in.spec, log_start_mm(r.motion));
    track.begin(Phase::Mapping, 0, 0);
    r.program = prepare_program_run(std::move(program), source.settings, r.motion, control);

    force_model::FeedOptimizerOptions search = in.search;
    search.commanded = r.program.commanded;
    // Each prediction of the search reports 0..1; it runs at most max_predictions + 3 of them.
    const double total = search.max_predictions + 3;
    int finished = 0;
    double last = 0;
    force_model::PredictOptions po;
    po.device = in.device;
    po.base_stock = in.base_stock;
    po.cancel = control.cancel;
    track.begin(Phase::Optimize, 0, 1);
    if (control.progress)
        po.progress = [&](double f) {
            if (f < last) ++finished;   // a new prediction started
            last = f;
            track.report(std::min(1.0, (finished + f) / total));
        };
    r.feeds = force_model::optimize_feeds(r.program.program, r.motion, in.spec, po, search);
    r.program_text = motion_io::rewrite_feeds(r.program.program, r.feeds.feed_mm_min);
    for (const auto& b : r.feeds.blocks)
        if (b.recommended_feed_mm_min != b.programmed_feed_mm_min) ++r.changed_blocks;
    track.done();
    return r;
}

}  // namespace

OptimizeResult optimize_feeds(const OptimizeInput& in, const Control& control) {
    return cancellable(control, [&] { return optimize_steps(in, control); });
}

}  // namespace cutload::app
