// Internal: the estimates behind stage "clock" (clock_recovery.hpp): the CNC's position-update
// period and tick phase from client readings.
//
// The CNC latches a new position every T seconds (4 ms on the seed's FANUC); the client reads at
// its own, drifting times. A reading taken at t shows the position latched at the last tick
// before t. If T and the tick phase are known, every reading gets the time of the tick it shows,
// and positions become exact samples of the motion: no beat is left to smooth away. This
// generalises the seed's eqs. 4.1/4.2, which pick the CNC samples by the phase offset alpha.
#pragma once

#include <cstddef>
#include <vector>

namespace cutload::motion_io::detail {

struct PosRead {
    double t_s = 0;
    double p_mm[3] = {0, 0, 0};
    double rot_deg[3] = {0, 0, 0};   // A, B, C (0 where the log has none)
};

// Whether any axis, linear or rotary, differs between two readings.
inline bool moved(const PosRead& a, const PosRead& b) {
    for (int k = 0; k < 3; ++k)
        if (a.p_mm[k] != b.p_mm[k] || a.rot_deg[k] != b.rot_deg[k]) return true;
    return false;
}

// The tick at or before t on the grid phase + k * period (period 0: t itself, no grid).
double tick_at_or_before(double t_s, double period_s, double phase_s);

// How much the velocity from consecutive readings jumps when each reading is timed at its tick
// (by tick index: an interval is a whole number of periods, whatever the grid's phase):
// mean over consecutive moving pairs of |v_k - v_k-1|^2 / (|v_k|^2 + |v_k-1|^2); two different
// positions on one tick count 1. 0 for a smooth motion. pairs (optional) receives the pairs used.
double tick_roughness(const PosRead* reads, std::size_t n, double period_s, double phase_s,
                      std::size_t* pairs = nullptr);

// tick_roughness(reads, n, period_s, period_s * (i + offset) / phases) for every i in [0, phases),
// into out[i], bit for bit, at about the cost of two evaluations: a reading changes tick at one
// phase of the scan, and only the terms next to it change there. last_pairs (optional) receives
// the pairs of the last phase. The period scans' inner loop.
void roughness_over_phases(const PosRead* reads, std::size_t n, double period_s, int phases, double offset,
                           double* out, std::size_t* last_pairs = nullptr);
// The least of those values, exactly, summing in order only the phases that can be the least.
double least_roughness_over_phases(const PosRead* reads, std::size_t n, double period_s, int phases, double offset);

// Fewest moving pairs of readings from which estimate_update_period() tries to find a grid.
inline constexpr std::size_t kMinPeriodPairs = 12;

struct UpdatePeriod {
    double period_s = 0;   // 0: not estimated
    // Set when the readings were too few to measure the period by its phase drift and the nominal
    // (round) period inside the range their time stamps allow, [min_s, max_s], was taken.
    bool nominal = false;
    double min_s = 0, max_s = 0;
};

// Estimated update period from readings of a moving machine; period 0 when the readings show no
// update grid that explains them better than their own time stamps (too few moving readings,
// event-driven logs, or already uniform sampling). `threads`: 2 lets a long scan take a second
// core; the same period either way.
UpdatePeriod estimate_update_period(const std::vector<PosRead>& reads, unsigned threads = 2);

// Whether a period explains the readings clearly better than their own time stamps: the test
// estimate_update_period() accepts a found period by. Cheap (no scan): for a period known from
// another stretch of the same log.
bool period_fits(const std::vector<PosRead>& reads, double period_s);

// Readings from which a scan for the period is made at the fine phase resolution (a stretch too
// short to show the phase drift); such a scan costs the most per reading.
inline constexpr std::size_t kShortStretchReads = 256;

// Tick phase (s, in [0, period)) that best explains reads[0..n); `fallback` when they barely move.
// The chosen phase is the middle of the range of equally good phases, far from read times.
// `phases` trial phases are compared.
double best_phase(const PosRead* reads, std::size_t n, double period_s, double fallback_s, int phases = 16);

}  // namespace cutload::motion_io::detail
