// How a front end follows and stops a long use case: progress and cancellation are parameters of
// every use case that takes time, the same for the CLI (a progress line, Ctrl-C) and the service
// (a progress column, POST .../cancel).
#pragma once

#include <atomic>
#include <functional>

namespace cutload::app {

// What a use case is doing. A use case goes through some of these in this order and ends with Done.
enum class Phase {
    Ingest,      // reading and repairing the log
    Program,     // reading the NC program
    Mapping,     // attributing the log's samples to program blocks
    Predict,     // forces of the actual motion
    Commanded,   // forces of the programmed motion
    Optimize,    // feed search (a few predictions)
    Calibrate,   // steady means of the tests, then the regressors
    Done,
};
const char* phase_name(Phase p);   // "ingest", "program", ...

struct Control {
    // Called from the calling thread with the phase that runs and the fraction of the whole use
    // case done (0..1, never decreasing); the last call is (Done, 1) once the result is complete.
    std::function<void(Phase phase, double fraction)> progress;
    // Set from any thread to stop: the use case throws force_model::Cancelled at its next check,
    // which comes between phases and, inside a prediction, every few angle steps. Once it is set,
    // a step that fails meanwhile (its input deleted with the job, say) ends in Cancelled too.
    const std::atomic<bool>* cancel = nullptr;
};

}  // namespace cutload::app
