#include "app/control.hpp"

#include "tracker.hpp"

#include "force_model/force_model.hpp"

#include <algorithm>

namespace cutload::app {

const char* phase_name(Phase p) {
    switch (p) {
        case Phase::Ingest: return "ingest";
        case Phase::Program: return "program";
        case Phase::Mapping: return "mapping";
        case Phase::Predict: return "predict";
        case Phase::Commanded: return "commanded";
        case Phase::Optimize: return "optimize";
        case Phase::Calibrate: return "calibrate";
        case Phase::Done: return "done";
    }
    return "?";
}

void Tracker::check() const {
    if (control_.cancel && control_.cancel->load()) throw force_model::Cancelled();
}

void Tracker::begin(Phase phase, double from, double to) {
    check();
    phase_ = phase;
    from_ = std::max(from, last_);
    to_ = std::max(to, from_);
    report(0);
}

void Tracker::report(double phase_fraction) {
    const double f = std::clamp(from_ + (to_ - from_) * std::clamp(phase_fraction, 0.0, 1.0), last_, 1.0);
    last_ = f;
    if (control_.progress) control_.progress(phase_, f);
}

std::function<void(double)> Tracker::engine_progress() {
    if (!control_.progress) return nullptr;
    return [this](double f) { report(f); };
}

void Tracker::done() {
    check();
    phase_ = Phase::Done;
    from_ = to_ = 1;
    report(1);
}

}  // namespace cutload::app
