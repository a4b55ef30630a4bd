// Readings of a CNC's latched position by a client on its own clock, as in the seed (001, 4.2.3):
// the CNC latches its position every period at phase + n * period; the client reads at its own
// cycle with Gaussian jitter and stamps by its own clock, which may run fast or slow (drift).
// Seeded, deterministic. Used by the clock and velocity stage tests.
#pragma once

#include "stages/clock.hpp"

#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

namespace cutload::motion_io::test {

struct CncReadSpec {
    double period_s = 0.004;          // CNC latch period
    double phase_s = 0.0013;          // time of the first tick
    double read_interval_s = 0.006;   // client cycle (longer than the period: no repeated reads)
    double jitter_s = 40e-6;          // standard deviation of each read time
    double client_drift = 0;          // client clock rate error: 1e-3 stamps 1.001 s per second
    double feed_mm_min = 6000;        // constant, along (0.6, 0.8, 0) from (10, 20, 30)
    double accel_mm_s2 = 0;           // constant acceleration on top (0: constant feed)
    double quantum_mm = 0.001;        // position resolution
    std::size_t reads = 2048;
    std::uint64_t seed = 1;
};

// Where the motion is at time t (true time).
inline double cnc_path_mm(const CncReadSpec& s, double t_s) {
    return s.feed_mm_min / 60.0 * t_s + 0.5 * s.accel_mm_s2 * t_s * t_s;
}

inline std::vector<detail::PosRead> cnc_reads(const CncReadSpec& s) {
    std::mt19937_64 rng(s.seed);
    std::normal_distribution<double> jitter(0.0, s.jitter_s);
    std::vector<detail::PosRead> out;
    const double dir[3] = {0.6, 0.8, 0.0}, start[3] = {10, 20, 30};
    for (std::size_t k = 0; k < s.reads; ++k) {
        const double read_t = 0.01 + static_cast<double>(k) * s.read_interval_s + jitter(rng);
        const double tick = s.phase_s + s.period_s * std::floor((read_t - s.phase_s) / s.period_s);
        const double d = cnc_path_mm(s, tick);
        detail::PosRead r;
        r.t_s = read_t * (1.0 + s.client_drift);
        for (int a = 0; a < 3; ++a) r.p_mm[a] = std::round((start[a] + dir[a] * d) / s.quantum_mm) * s.quantum_mm;
        out.push_back(r);
    }
    return out;
}

}  // namespace cutload::motion_io::test
