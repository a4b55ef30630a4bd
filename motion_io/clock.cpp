#include "motion_io/clock.hpp"

#include <algorithm>
#include <cmath>

namespace cutload::motion_io::detail {
namespace {

bool moved(const PosRead& a, const PosRead& b) {
    return a.p_mm[0] != b.p_mm[0] || a.p_mm[1] != b.p_mm[1] || a.p_mm[2] != b.p_mm[2];
}

std::size_t count_moving_pairs(const PosRead* r, std::size_t n) {
    std::size_t c = 0;
    for (std::size_t k = 1; k < n; ++k) c += moved(r[k - 1], r[k]);
    return c;
}

// The prefix of reads holding `pairs` moving pairs (or all of them).
std::size_t prefix_with_moving_pairs(const std::vector<PosRead>& r, std::size_t pairs) {
    std::size_t c = 0;
    for (std::size_t k = 1; k < r.size(); ++k)
        if (moved(r[k - 1], r[k]) && ++c >= pairs) return k + 1;
    return r.size();
}

double median_interval(const std::vector<PosRead>& r) {
    std::vector<double> dt;
    dt.reserve(r.size());
    for (std::size_t k = 1; k < r.size(); ++k) dt.push_back(r[k].t_s - r[k - 1].t_s);
    if (dt.empty()) return 0;
    std::nth_element(dt.begin(), dt.begin() + static_cast<long>(dt.size() / 2), dt.end());
    return dt[dt.size() / 2];
}

constexpr int kCoarsePhases = 16;
constexpr std::size_t kTrackChunk = 64;   // readings per phase estimate, as the repair uses them

// Roughness with the phase re-chosen for every chunk of readings, as the repair tracks it: a
// slightly wrong period or a drifting client clock then costs nothing, a wrong period a lot.
double tracked_roughness(const PosRead* r, std::size_t n, double period_s, int phases) {
    double sum = 0;
    std::size_t chunks = 0;
    for (std::size_t s = 0; s + 1 < n; s += kTrackChunk) {
        const std::size_t m = std::min(n - s, kTrackChunk + 1);
        double best = 1e300;
        for (int i = 0; i < phases; ++i)
            best = std::min(best, tick_roughness(r + s, m, period_s, period_s * (i + 0.5) / phases));
        sum += best;
        ++chunks;
    }
    return chunks ? sum / static_cast<double>(chunks) : 0.0;
}

struct Candidate {
    double period_s;
    double roughness;
};

// Scans periods geometrically in [lo, hi]; returns the `keep` best local minima, best first.
std::vector<Candidate> scan_periods(const PosRead* r, std::size_t n, double lo, double hi, double rel_step,
                                    std::size_t keep) {
    std::vector<Candidate> all;
    for (double T = lo; T <= hi; T *= 1.0 + rel_step) all.push_back({T, tracked_roughness(r, n, T, kCoarsePhases)});
    std::vector<Candidate> minima;
    for (std::size_t i = 0; i < all.size(); ++i) {
        const bool left = i == 0 || all[i].roughness <= all[i - 1].roughness;
        const bool right = i + 1 == all.size() || all[i].roughness <= all[i + 1].roughness;
        if (left && right) minima.push_back(all[i]);
    }
    std::sort(minima.begin(), minima.end(), [](const Candidate& a, const Candidate& b) { return a.roughness < b.roughness; });
    if (minima.size() > keep) minima.resize(keep);
    return minima;
}

// A period slightly off makes the best phase drift steadily from chunk to chunk: a tick at time t
// sits at phase (t * (T_true - T) / T_true) mod T on the trial grid. The slope of the unwrapped
// phase against time gives T_true far more precisely than any scan over a short stretch.
double refine_by_phase_drift(const std::vector<PosRead>& reads, double T) {
    std::vector<double> tm, ph;
    double prev = -1, unwrap = 0;
    for (std::size_t s = 0; s + kTrackChunk < reads.size(); s += kTrackChunk) {
        const double p = best_phase(reads.data() + s, kTrackChunk + 1, T, -1);
        if (p < 0) continue;
        if (prev >= 0) {
            double d = p - prev;
            d -= T * std::round(d / T);
            unwrap += d;
        }
        prev = p;
        tm.push_back(reads[s + kTrackChunk / 2].t_s);
        ph.push_back(unwrap);
    }
    if (tm.size() < 4) return T;
    double mt = 0, mp = 0;
    for (std::size_t i = 0; i < tm.size(); ++i) mt += tm[i], mp += ph[i];
    mt /= static_cast<double>(tm.size()), mp /= static_cast<double>(tm.size());
    double sxy = 0, sxx = 0;
    for (std::size_t i = 0; i < tm.size(); ++i) sxy += (tm[i] - mt) * (ph[i] - mp), sxx += (tm[i] - mt) * (tm[i] - mt);
    if (sxx <= 0) return T;
    const double slope = sxy / sxx;
    return std::fabs(slope) < 0.01 ? T / (1.0 - slope) : T;
}

}  // namespace

double tick_at_or_before(double t_s, double period_s, double phase_s) {
    if (period_s <= 0) return t_s;
    return phase_s + period_s * std::floor((t_s - phase_s) / period_s);
}

double tick_roughness(const PosRead* r, std::size_t n, double period_s, double phase_s, std::size_t* pairs_out) {
    double cost = 0;
    std::size_t pairs = 0;
    bool have_v = false;
    double pv[3] = {0, 0, 0};
    double g_prev = n ? tick_at_or_before(r[0].t_s, period_s, phase_s) : 0;
    for (std::size_t k = 1; k < n; ++k) {
        const double g = tick_at_or_before(r[k].t_s, period_s, phase_s);
        const double dg = g - g_prev;
        g_prev = g;
        if (!moved(r[k - 1], r[k])) {
            have_v = false;
            continue;
        }
        if (dg <= 0) {
            cost += 1;
            ++pairs;
            have_v = false;
            continue;
        }
        double v[3], dv2 = 0, s2 = 0;
        for (int a = 0; a < 3; ++a) {
            v[a] = (r[k].p_mm[a] - r[k - 1].p_mm[a]) / dg;
            dv2 += (v[a] - pv[a]) * (v[a] - pv[a]);
            s2 += v[a] * v[a] + pv[a] * pv[a];
        }
        if (have_v) {
            cost += dv2 / s2;
            ++pairs;
        }
        std::copy(v, v + 3, pv);
        have_v = true;
    }
    if (pairs_out) *pairs_out = pairs;
    return pairs ? cost / static_cast<double>(pairs) : 0.0;
}

double estimate_update_period(const std::vector<PosRead>& reads) {
    constexpr std::size_t kMinPairs = 40;
    if (count_moving_pairs(reads.data(), reads.size()) < kMinPairs) return 0;
    const double med = median_interval(reads);
    const double lo = 0.5e-3, hi = std::min(0.05, 3 * med);
    if (hi <= lo) return 0;
    // Coarse on a short stretch (a coarse period step builds up little phase error there), then
    // the few best local minima fine on a longer one: a stretch where the reads sit right at the
    // ticks can make a wrong period look good on the short stretch, never on the long one.
    const std::size_t n_coarse = prefix_with_moving_pairs(reads, 128);
    const std::size_t n_fine = prefix_with_moving_pairs(reads, 512);
    double T = 0, best = 1e300;
    for (const Candidate& c : scan_periods(reads.data(), n_coarse, lo, hi, 2.5e-3, 5)) {
        const auto fine = scan_periods(reads.data(), n_fine, c.period_s * (1 - 5e-3), c.period_s * (1 + 5e-3), 2.5e-4, 1);
        if (!fine.empty() && fine.front().roughness < best) best = fine.front().roughness, T = fine.front().period_s;
    }
    if (T == 0) return 0;
    T = refine_by_phase_drift(reads, T);
    const double rough = tracked_roughness(reads.data(), reads.size(), T, 32);
    const double raw = tracked_roughness(reads.data(), reads.size(), 0, 1);
    // Accept only a clear improvement over the readings' own time stamps, and only when they
    // show a beat at all. A "grid" as fine as the reads themselves would merely erase their
    // jitter and rescale the velocity: the time stamps are then the better clock.
    if (raw < 1e-3 || std::fabs(T / med - 1.0) < 0.05) return 0;
    return rough < 0.3 * raw ? T : 0.0;
}

double best_phase(const PosRead* r, std::size_t n, double period_s, double fallback_s) {
    constexpr int kPhases = 16;
    if (period_s <= 0) return 0;
    std::size_t pairs = 0;
    double rough[kPhases];
    double best = 1e300;
    for (int i = 0; i < kPhases; ++i) {
        rough[i] = tick_roughness(r, n, period_s, period_s * i / kPhases, &pairs);
        best = std::min(best, rough[i]);
    }
    if (pairs < 8) return fallback_s;
    // Middle of the longest circular run of near-best phases: the tick grid then sits as far as
    // possible from the read times, so time-stamp jitter does not move a reading to another tick.
    // One reading put on a wrong tick adds about 0.4 / pairs; position quantisation far less.
    const double tol = best + 0.1 / static_cast<double>(std::max<std::size_t>(pairs, 1));
    int best_start = 0, best_len = 0;
    for (int start = 0; start < kPhases; ++start) {
        if (rough[start] > tol || rough[(start + kPhases - 1) % kPhases] <= tol) continue;
        int len = 0;
        while (len < kPhases && rough[(start + len) % kPhases] <= tol) ++len;
        if (len > best_len) best_len = len, best_start = start;
    }
    if (best_len == 0) return fallback_s;  // every phase equally good: nothing to learn here
    const double mid = best_start + (best_len - 1) / 2.0;
    return period_s * std::fmod(mid, kPhases) / kPhases;
}

}  // namespace cutload::motion_io::detail
