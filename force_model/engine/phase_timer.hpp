// Internal: wall time of the engine's phases (EnginePhases).
#pragma once

#include <chrono>

namespace cutload::force_model {

using Clock = std::chrono::steady_clock;

// Adds the time from construction to destruction to `acc_s`.
class PhaseTimer {
public:
    explicit PhaseTimer(double& acc_s) : acc_s_(acc_s), start_(Clock::now()) {}
    PhaseTimer(const PhaseTimer&) = delete;
    PhaseTimer& operator=(const PhaseTimer&) = delete;
    ~PhaseTimer() { acc_s_ += std::chrono::duration<double>(Clock::now() - start_).count(); }

private:
    double& acc_s_;
    Clock::time_point start_;
};

}  // namespace cutload::force_model
