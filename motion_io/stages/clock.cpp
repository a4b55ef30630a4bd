#include "stages/clock.hpp"

#include <algorithm>
#include <cmath>
#include <optional>

namespace cutload::motion_io::detail {
namespace {

bool moved(const PosRead& a, const PosRead& b) {
    return a.p_mm[0] != b.p_mm[0] || a.p_mm[1] != b.p_mm[1] || a.p_mm[2] != b.p_mm[2];
}

// Where a reading lies on the grid: its tick index (period > 0), or its own time stamp (no grid).
// Indices, not tick times: the interval between two readings is then a whole number of periods
// whatever the grid's phase or the log's time origin (tick times far from zero would add their
// rounding), so grids that put every reading on the same tick give bit-identical roughness.
double tick_position(double t_s, double period_s, double phase_s) {
    return period_s > 0 ? std::floor((t_s - phase_s) / period_s) : t_s;
}

double tick_interval(double cur, double prev, double period_s) {
    return period_s > 0 ? period_s * (cur - prev) : cur - prev;
}

void velocity(const PosRead& a, const PosRead& b, double dg, double v[3]) {
    for (int ax = 0; ax < 3; ++ax) v[ax] = (b.p_mm[ax] - a.p_mm[ax]) / dg;
}

// |v - pv|^2 / (|v|^2 + |pv|^2): 0 for a steady velocity, up to 2 for a reversal.
double velocity_jump(const double v[3], const double pv[3]) {
    double dv2 = 0, s2 = 0;
    for (int ax = 0; ax < 3; ++ax) {
        dv2 += (v[ax] - pv[ax]) * (v[ax] - pv[ax]);
        s2 += v[ax] * v[ax] + pv[ax] * pv[ax];
    }
    return dv2 / s2;
}

struct RoughnessSum {
    double cost = 0;
    std::size_t pairs = 0;
    void add(double c, std::size_t p) { cost += c, pairs += p; }
    double value() const { return pairs ? cost / static_cast<double>(pairs) : 0.0; }
};

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
constexpr std::size_t kTrustedPairs = 40;   // moving pairs from which a scanned period is used
// On a stretch too short to track the phase chunk by chunk, the window of good phases can be
// narrower than a coarse phase step (readings within tens of microseconds of a tick); missing it
// makes a wrong period look best.
constexpr int kFinePhases = 256;
constexpr std::size_t kTrackChunk = 64;   // readings per phase estimate, as the repair uses them
// Fewer readings than kShortStretchReads span too few chunks for the phase drift to refine the period.
static_assert(kShortStretchReads == 4 * kTrackChunk);

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
                                    std::size_t keep, int phases) {
    std::vector<Candidate> all;
    for (double T = lo; T <= hi; T *= 1.0 + rel_step) all.push_back({T, tracked_roughness(r, n, T, phases)});
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
// 0 when the readings span too few chunks to show a drift.
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
    if (tm.size() < 4) return 0;
    double mt = 0, mp = 0;
    for (std::size_t i = 0; i < tm.size(); ++i) mt += tm[i], mp += ph[i];
    mt /= static_cast<double>(tm.size()), mp /= static_cast<double>(tm.size());
    double sxy = 0, sxx = 0;
    for (std::size_t i = 0; i < tm.size(); ++i) sxy += (tm[i] - mt) * (ph[i] - mp), sxx += (tm[i] - mt) * (tm[i] - mt);
    if (sxx <= 0) return T;
    const double slope = sxy / sxx;
    return std::fabs(slope) < 0.01 ? T / (1.0 - slope) : T;
}

// Bounds the time stamps put on the tick grid, one per reading that shows or precedes a change.
struct TickBound {
    double t_s, n;        // time since the first tick, tick index
    bool lower, upper;    // the reading shows a new position / is followed by one
};

std::vector<TickBound> tick_bounds(const std::vector<PosRead>& reads, double T, double phase) {
    // Relative to the first tick, so that n * T stays small.
    const double tick0 = tick_at_or_before(reads.front().t_s, T, phase);
    std::vector<TickBound> bounds;
    for (std::size_t k = 0; k < reads.size(); ++k) {
        const bool lower = k > 0 && moved(reads[k - 1], reads[k]);
        const bool upper = k + 1 < reads.size() && moved(reads[k], reads[k + 1]);
        if (!lower && !upper) continue;
        const double t = reads[k].t_s - tick0;
        bounds.push_back({t, std::floor(t / T), lower, upper});
    }
    return bounds;
}

double window_width(const std::vector<TickBound>& bounds, double T) {
    double hi = 1e300, lo = -1e300;
    for (const TickBound& b : bounds) {
        if (b.lower) hi = std::min(hi, b.t_s - b.n * T);
        if (b.upper) lo = std::max(lo, b.t_s - (b.n + 1) * T);
    }
    return hi - lo;
}

// Golden-section search of the concave window width over [a, b].
double widest_window_period(const std::vector<TickBound>& bounds, double a, double b) {
    constexpr double kInvPhi = 0.6180339887498949;
    double c = b - kInvPhi * (b - a), d = a + kInvPhi * (b - a);
    double wc = window_width(bounds, c), wd = window_width(bounds, d);
    for (int i = 0; i < 80; ++i) {
        if (wc >= wd) {
            b = d, d = c, wd = wc;
            c = b - kInvPhi * (b - a), wc = window_width(bounds, c);
        } else {
            a = c, c = d, wc = wd;
            d = a + kInvPhi * (b - a), wd = window_width(bounds, d);
        }
    }
    return 0.5 * (a + b);
}

// The roundest period in [lo, hi] (a multiple of 1, 0.5, 0.25 or 0.125 ms, nearest to `near`);
// 0 when there is none.
double nominal_period_in(double lo, double hi, double near) {
    for (double step_s : {1e-3, 0.5e-3, 0.25e-3, 0.125e-3}) {
        double pick = 0;
        for (double m : {std::floor(near / step_s), std::ceil(near / step_s)}) {
            const double T = m * step_s;
            if (T >= lo && T <= hi && (pick == 0 || std::fabs(T - near) < std::fabs(pick - near))) pick = T;
        }
        if (pick > 0) return pick;
    }
    return 0;
}

// On a stretch too short to show a phase drift the roughness cannot fix the period: it compares
// velocities only, and every period that keeps each reading on the same tick scales them all
// alike. The time stamps bound it. With the tick index n_k of every reading fixed by the trial
// grid, a reading that shows a new position lies at or after its tick and one followed by a new
// position lies before the next tick, so the phase must satisfy
//   t_k - (n_k + 1) T < phase <= t_k - n_k T.
// The width of that window is concave in T; the periods where it is positive are all the stamps
// allow. In the seed's pattern the read phase only alternates between two values and wanders
// slowly, so 20 readings allow about +-2 %: too loose for a feed. CNCs run their position loop
// at a nominal period, a round number of milliseconds (the seed's FANUC: 4 ms), so the roundest
// period in the range is taken, its error bounded by the range (the caller warns). Without a
// nominal period inside it: nullopt (motion that changes speed can put a reading near a tick on
// its neighbour, and the range then misses the true period).
std::optional<UpdatePeriod> nominal_period_from_bounds(const std::vector<PosRead>& reads, double T0) {
    const double search_lo = T0 / 1.05, search_hi = T0 * 1.05;
    // The ticks are assigned on the trial grid, the period of least roughness: not re-assigned
    // on the widest window's, which a slow wander of the read phase can pull off by a few per
    // cent, where a reading at a change of motion then lands on another tick.
    const double phase = best_phase(reads.data(), reads.size(), T0, -1, kFinePhases);
    if (phase < 0) return std::nullopt;
    const std::vector<TickBound> bounds = tick_bounds(reads, T0, phase);
    const double T = widest_window_period(bounds, search_lo, search_hi);
    if (window_width(bounds, T) <= 0) return std::nullopt;   // stamps too noisy to bound the period
    // Ends of the range where the window closes (it is concave: one interval).
    auto edge = [&](double inside, double outside) {
        if (window_width(bounds, outside) > 0) return outside;
        for (int i = 0; i < 60; ++i) {
            const double mid = 0.5 * (inside + outside);
            (window_width(bounds, mid) > 0 ? inside : outside) = mid;
        }
        return inside;
    };
    UpdatePeriod out;
    out.min_s = edge(T, search_lo);
    out.max_s = edge(T, search_hi);
    out.period_s = nominal_period_in(out.min_s, out.max_s, T);
    out.nominal = true;
    if (out.period_s == 0) return std::nullopt;
    return out;
}

}  // namespace

double tick_at_or_before(double t_s, double period_s, double phase_s) {
    if (period_s <= 0) return t_s;
    return phase_s + period_s * std::floor((t_s - phase_s) / period_s);
}

double tick_roughness(const PosRead* r, std::size_t n, double period_s, double phase_s, std::size_t* pairs_out) {
    RoughnessSum sum;
    bool have_v = false;
    double pv[3] = {0, 0, 0};
    double prev = n ? tick_position(r[0].t_s, period_s, phase_s) : 0;
    for (std::size_t k = 1; k < n; ++k) {
        const double cur = tick_position(r[k].t_s, period_s, phase_s);
        const double dg = tick_interval(cur, prev, period_s);
        prev = cur;
        if (!moved(r[k - 1], r[k])) {
            have_v = false;
            continue;
        }
        if (dg <= 0) {
            sum.add(1.0, 1);
            have_v = false;
            continue;
        }
        double v[3];
        velocity(r[k - 1], r[k], dg, v);
        if (have_v) sum.add(velocity_jump(v, pv), 1);
        std::copy(v, v + 3, pv);
        have_v = true;
    }
    if (pairs_out) *pairs_out = sum.pairs;
    return sum.value();
}

UpdatePeriod estimate_update_period(const std::vector<PosRead>& reads) {
    const std::size_t pairs = count_moving_pairs(reads.data(), reads.size());
    if (pairs < kMinPeriodPairs) return {};
    const double med = median_interval(reads);
    const double lo = 0.5e-3, hi = std::min(0.05, 3 * med);
    if (hi <= lo) return {};
    // Coarse on a short stretch (a coarse period step builds up little phase error there), then
    // the few best local minima fine on a longer one: a stretch where the reads sit right at the
    // ticks can make a wrong period look good on the short stretch, never on the long one.
    const std::size_t n_coarse = prefix_with_moving_pairs(reads, 128);
    const std::size_t n_fine = prefix_with_moving_pairs(reads, 512);
    auto scan = [&](int phases) {
        double T = 0, best = 1e300;
        for (const Candidate& c : scan_periods(reads.data(), n_coarse, lo, hi, 2.5e-3, 5, phases)) {
            const auto fine =
                scan_periods(reads.data(), n_fine, c.period_s * (1 - 5e-3), c.period_s * (1 + 5e-3), 2.5e-4, 1, phases);
            if (!fine.empty() && fine.front().roughness < best) best = fine.front().roughness, T = fine.front().period_s;
        }
        return T;
    };
    auto accepted = [&](double T) { return period_fits(reads, T); };
    // A stretch too short for the phase drift: the nominal period the time stamps allow, if any
    // (per cent closer than the scan there), and if it fits the readings.
    if (reads.size() <= kShortStretchReads) {
        if (const double T = scan(kFinePhases); T > 0) {
            const std::optional<UpdatePeriod> bounded = nominal_period_from_bounds(reads, T);
            if (bounded && accepted(bounded->period_s)) return *bounded;
        }
    }
    // Otherwise the scan, refined by the phase drift where the stretch is long enough; with fewer
    // than kTrustedPairs the scan alone is too loose (per cent) to be used.
    if (pairs < kTrustedPairs) return {};
    const double T = scan(kCoarsePhases);
    if (T == 0) return {};
    const double drift_T = refine_by_phase_drift(reads, T);
    UpdatePeriod out;
    out.period_s = drift_T > 0 ? drift_T : T;
    if (!accepted(out.period_s)) return {};
    return out;
}

bool period_fits(const std::vector<PosRead>& reads, double period_s) {
    if (!(period_s > 0)) return false;
    const double med = median_interval(reads);
    const double raw = tracked_roughness(reads.data(), reads.size(), 0, 1);
    // Accept only a clear improvement over the readings' own time stamps, and only when they
    // show a beat at all. A "grid" as fine as the reads themselves would merely erase their
    // jitter and rescale the velocity: the time stamps are then the better clock.
    return raw >= 1e-3 && std::fabs(period_s / med - 1.0) >= 0.05 &&
           tracked_roughness(reads.data(), reads.size(), period_s, 32) < 0.3 * raw;
}

double best_phase(const PosRead* r, std::size_t n, double period_s, double fallback_s, int phases) {
    if (period_s <= 0) return 0;
    std::size_t pairs = 0;
    std::vector<double> rough(static_cast<std::size_t>(phases));
    double best = 1e300;
    for (int i = 0; i < phases; ++i) {
        rough[static_cast<std::size_t>(i)] = tick_roughness(r, n, period_s, period_s * i / phases, &pairs);
        best = std::min(best, rough[static_cast<std::size_t>(i)]);
    }
    if (pairs < 8) return fallback_s;
    // Middle of the longest circular run of near-best phases: the tick grid then sits as far as
    // possible from the read times, so time-stamp jitter does not move a reading to another tick.
    // One reading put on a wrong tick adds about 0.4 / pairs; position quantisation far less.
    const double tol = best + 0.1 / static_cast<double>(std::max<std::size_t>(pairs, 1));
    int best_start = 0, best_len = 0;
    for (int start = 0; start < phases; ++start) {
        if (rough[static_cast<std::size_t>(start)] > tol || rough[static_cast<std::size_t>((start + phases - 1) % phases)] <= tol)
            continue;
        int len = 0;
        while (len < phases && rough[static_cast<std::size_t>((start + len) % phases)] <= tol) ++len;
        if (len > best_len) best_len = len, best_start = start;
    }
    if (best_len == 0) return fallback_s;  // every phase equally good: nothing to learn here
    const double mid = best_start + (best_len - 1) / 2.0;
    return period_s * std::fmod(mid, phases) / phases;
}

}  // namespace cutload::motion_io::detail
