// Internal to app: a use case's progress and cancellation, phase by phase.
#pragma once

#include "app/control.hpp"
#include "force_model/force_model.hpp"

#include <exception>
#include <functional>

namespace cutload::app {

class Tracker {
public:
    explicit Tracker(const Control& control) : control_(control) {}

    // Throws force_model::Cancelled when a cancel was asked for.
    void check() const;
    // Checks for a cancel, then starts `phase`, which takes the fractions [from, to] of the whole.
    void begin(Phase phase, double from, double to);
    // Progress within the current phase (0..1); the whole never goes back.
    void report(double phase_fraction);
    // The engine's progress callback for the current phase (predictions report 0..1 each).
    std::function<void(double)> engine_progress();
    // Checks for a cancel, then reports (Done, 1).
    void done();

private:
    const Control& control_;
    Phase phase_ = Phase::Ingest;
    double from_ = 0, to_ = 0, last_ = 0;
};

// Runs a use case. Once a cancel was asked for, a failure of the step it interrupted is the cancel
// (the service deletes a run's files right after cancelling the job that reads them), so the
// front end sees Cancelled either way.
template <class UseCase>
auto cancellable(const Control& control, UseCase&& use_case) -> decltype(use_case()) {
    try {
        return use_case();
    } catch (const force_model::Cancelled&) {
        throw;
    } catch (const std::exception&) {
        if (control.cancel && control.cancel->load()) throw force_model::Cancelled();
        throw;
    }
}

}  // namespace cutload::app
