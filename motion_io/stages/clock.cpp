#include "stages/clock.hpp"

#include "pipeline.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <exception>
#include <optional>
#include <system_error>
#include <thread>

namespace cutload::motion_io::detail {
namespace {

// Velocities in joint space: x, y, z in mm/s, then A, B, C as mm/s at kRotaryMmPerDeg, so a pure
// rotary move has a velocity to judge. Without rotary axes the last three are 0 and every sum
// below is what it was over x, y, z alone, bit for bit.
constexpr int kJointDims = 6;

// Where a reading lies on the grid: its tick index (period > 0), or its own time stamp (no grid).
// Indices, not tick times: the interval between two readings is then a whole number of periods
// whatever the grid's phase or the log's time origin (tick times far from zero would add their
// rounding), so grids that put every reading on the same tick give bit-identical roughness (what
// the phase scan below relies on).
double tick_position(double t_s, double period_s, double phase_s) {
    return period_s > 0 ? std::floor((t_s - phase_s) / period_s) : t_s;
}

double tick_interval(double cur, double prev, double period_s) {
    return period_s > 0 ? period_s * (cur - prev) : cur - prev;
}

// Dims = 3 leaves the rotary components as they are: for readings whose rotary axes stand still
// (equal angles) they are +0 either way, and the sums below then add +0 for each of them, which
// changes no value: the same bits as kJointDims, without half the divisions.
template <int Dims = kJointDims>
void velocity(const PosRead& a, const PosRead& b, double dg, double v[kJointDims]) {
    for (int ax = 0; ax < 3; ++ax) v[ax] = (b.p_mm[ax] - a.p_mm[ax]) / dg;
    for (int ax = 0; ax < Dims - 3; ++ax) v[3 + ax] = (b.rot_deg[ax] - a.rot_deg[ax]) * kRotaryMmPerDeg / dg;
}

// |v - pv|^2 / (|v|^2 + |pv|^2): 0 for a steady velocity, up to 2 for a reversal.
template <int Dims = kJointDims>
double velocity_jump(const double v[kJointDims], const double pv[kJointDims]) {
    double dv2 = 0, s2 = 0;
    for (int ax = 0; ax < Dims; ++ax) {
        dv2 += (v[ax] - pv[ax]) * (v[ax] - pv[ax]);
        s2 += v[ax] * v[ax] + pv[ax] * pv[ax];
    }
    return dv2 / s2;
}

// Whether any two successive readings differ in a rotary axis (NaNs count as differing).
bool rotary_moves(const PosRead* r, std::size_t n) {
    for (std::size_t k = 1; k < n; ++k)
        for (int ax = 0; ax < 3; ++ax)
            if (!(r[k].rot_deg[ax] == r[k - 1].rot_deg[ax])) return true;
    return false;
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

class PhaseScan;
double least_roughness_over_phases(PhaseScan& scan, const PosRead* r, std::size_t n, double period_s, int phases,
                                   double offset);

// Roughness with the phase re-chosen for every chunk of readings, as the repair tracks it: a
// slightly wrong period or a drifting client clock then costs nothing, a wrong period a lot.
double tracked_roughness(PhaseScan& scan, const PosRead* r, std::size_t n, double period_s, int phases) {
    double sum = 0;
    std::size_t chunks = 0;
    for (std::size_t s = 0; s + 1 < n; s += kTrackChunk) {
        const std::size_t m = std::min(n - s, kTrackChunk + 1);
        sum += least_roughness_over_phases(scan, r + s, m, period_s, phases, 0.5);
        ++chunks;
    }
    return chunks ? sum / static_cast<double>(chunks) : 0.0;
}

double tracked_roughness(const PosRead* r, std::size_t n, double period_s, int phases);

struct Candidate {
    double period_s;
    double roughness;
};

// Below this many reading-phase evaluations a scan is not worth a second thread (about 1 ms).
constexpr double kParallelScanWork = 2e6;

// Scans periods geometrically in [lo, hi]; returns the `keep` best local minima, best first.
std::vector<Candidate> scan_periods(const PosRead* r, std::size_t n, double lo, double hi, double rel_step,
                                    std::size_t keep, int phases, unsigned threads);

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
    double pv[kJointDims] = {0, 0, 0, 0, 0, 0};
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
        double v[kJointDims];
        velocity(r[k - 1], r[k], dg, v);
        if (have_v) sum.add(velocity_jump(v, pv), 1);
        std::copy(v, v + kJointDims, pv);
        have_v = true;
    }
    if (pairs_out) *pairs_out = sum.pairs;
    return sum.value();
}

namespace {

// The scan behind roughness_over_phases and least_roughness_over_phases: tick_roughness(r, n, T,
// T * (i + offset) / phases) for i = 0, 1, ..., phases - 1. Each reading's tick index falls by one
// at one phase of the scan (monotonically: floor((t - phase) / T) never rises with the phase, and
// the phases span less than a period), so moving to the next phase changes the velocities of the
// pairs next to the readings that changed tick, and three terms of the roughness sum each. The
// sum is then redone in tick_roughness's order, so a value equals tick_roughness's bit for bit.
// With `out` null only the least value is wanted: a phase whose running (unordered) sum proves
// it larger than the least so far is not summed in order.
class PhaseScan {
public:
    // False where the bookkeeping does not apply (no grid, a tick index that falls by more than
    // one across the scan); the caller then evaluates phase by phase.
    bool run(const PosRead* r, std::size_t n, double period_s, int phases, double offset, double* out, double* least,
             std::size_t* last_pairs) {
        r_ = r, n_ = n, period_s_ = period_s;
        if (!(period_s > 0) || phases < 2 || n < 3) return false;
        rotary_ = rotary_moves(r, n);
        auto phase_at = [&](int i) { return period_s * (i + offset) / phases; };
        idx_.resize(n), dropped_.resize(n), drop_at_.assign(n, phases);
        bucket_start_.assign(static_cast<std::size_t>(phases) + 1, 0);
        const double first = phase_at(0), last = phase_at(phases - 1);
        for (std::size_t k = 0; k < n; ++k) {
            const double t = r[k].t_s;
            idx_[k] = tick_position(t, period_s, first);
            dropped_[k] = tick_position(t, period_s, last);
            if (dropped_[k] == idx_[k]) continue;
            if (dropped_[k] != idx_[k] - 1) return false;
            // First phase at which the index has dropped: estimated from where t lies between
            // ticks, then settled with tick_position itself (what the grid does decides).
            const double residue = (t - idx_[k] * period_s) / period_s * phases - offset;
            int i = std::clamp(static_cast<int>(std::floor(residue)) + 1, 1, phases - 1);
            while (i > 1 && tick_position(t, period_s, phase_at(i - 1)) != idx_[k]) --i;
            while (i < phases - 1 && tick_position(t, period_s, phase_at(i)) == idx_[k]) ++i;
            drop_at_[k] = i;
            ++bucket_start_[static_cast<std::size_t>(i) + 1];
        }
        // Readings by the phase they drop at (counting sort; in reading order within a phase).
        for (int i = 0; i < phases; ++i) bucket_start_[static_cast<std::size_t>(i) + 1] += bucket_start_[static_cast<std::size_t>(i)];
        order_.resize(bucket_start_[static_cast<std::size_t>(phases)]);
        fill_ = bucket_start_;
        for (std::size_t k = 0; k < n; ++k)
            if (drop_at_[k] < phases) order_[fill_[static_cast<std::size_t>(drop_at_[k])]++] = k;

        moving_.assign(n, 0), ahead_.assign(n, 0), counted_.assign(n, 0);
        v_.assign(kJointDims * n, 0.0), term_.assign(n, 0.0);
        for (std::size_t k = 1; k < n; ++k) moving_[k] = moved(r[k - 1], r[k]), update_pair(k);
        for (std::size_t k = 1; k < n; ++k) update_term(k);
        RoughnessSum exact = ordered_sum();
        double running = exact.cost;   // the same sum kept by differences: off by rounding only
        std::size_t pairs = exact.pairs;
        bool exact_now = true;
        double best = 1e300;
        // Bound on the running sum's rounding: at most 7 n additions (n to start, then three terms
        // out and in per reading that changes tick), each off by eps of a partial sum that stays
        // below 2 n + 2 (a term is at most 2).
        const double nd = static_cast<double>(n);
        const double margin = 1e-12 + 7 * nd * (2 * nd + 2) * std::numeric_limits<double>::epsilon();
        for (int i = 0; i < phases; ++i) {
            const std::size_t b0 = bucket_start_[static_cast<std::size_t>(i)], b1 = bucket_start_[static_cast<std::size_t>(i) + 1];
            if (b0 < b1) {
                std::size_t lo = n, hi = 0;   // pairs whose velocity changes
                for (std::size_t j = b0; j < b1; ++j) {
                    const std::size_t k = order_[j];
                    idx_[k] = dropped_[k];
                    lo = std::min(lo, std::max<std::size_t>(k, 1));
                    hi = std::max(hi, std::min(k + 1, n - 1));
                }
                for (std::size_t k = lo; k <= hi; ++k) update_pair(k);
                for (std::size_t k = lo; k <= std::min(hi + 1, n - 1); ++k) {
                    running -= term_[k], pairs -= counted_[k];
                    update_term(k);
                    running += term_[k], pairs += counted_[k];
                }
                exact_now = false;
            }
            if (out != nullptr) {
                if (!exact_now) exact = ordered_sum(), exact_now = true;
                out[i] = exact.value();
                continue;
            }
            // A phase the running sum shows worse than the best by more than its rounding cannot be
            // the least.
            if (pairs > 0 && (running - margin) / static_cast<double>(pairs) > best) continue;
            if (!exact_now) exact = ordered_sum(), exact_now = true;
            best = std::min(best, exact.value());
        }
        if (least) *least = best;
        if (last_pairs) *last_pairs = pairs;
        return true;
    }

private:
    void update_pair(std::size_t k) {
        const double dg = tick_interval(idx_[k], idx_[k - 1], period_s_);
        ahead_[k] = dg > 0;
        if (!moving_[k] || !ahead_[k]) return;
        if (rotary_) velocity(r_[k - 1], r_[k], dg, &v_[kJointDims * k]);
        else velocity<3>(r_[k - 1], r_[k], dg, &v_[kJointDims * k]);   // the rotary parts stay +0
    }
    // Pair k's term of tick_roughness's sum: none when it did not move or the pair before did not
    // give a velocity, 1 for two positions on one tick.
    void update_term(std::size_t k) {
        if (!moving_[k]) term_[k] = 0, counted_[k] = 0;
        else if (!ahead_[k]) term_[k] = 1.0, counted_[k] = 1;
        else if (k >= 2 && moving_[k - 1] && ahead_[k - 1])
            term_[k] = rotary_ ? velocity_jump(&v_[kJointDims * k], &v_[kJointDims * (k - 1)])
                               : velocity_jump<3>(&v_[kJointDims * k], &v_[kJointDims * (k - 1)]),
            counted_[k] = 1;
        else term_[k] = 0, counted_[k] = 0;
    }
    RoughnessSum ordered_sum() const {
        RoughnessSum sum;
        for (std::size_t k = 1; k < n_; ++k)
            if (counted_[k]) sum.add(term_[k], counted_[k]);
        return sum;
    }

    const PosRead* r_ = nullptr;
    std::size_t n_ = 0;
    double period_s_ = 0;
    bool rotary_ = false;   // some reading turns a rotary axis: all six velocity components
    std::vector<double> idx_, dropped_, v_, term_;
    std::vector<int> drop_at_;
    std::vector<std::size_t> bucket_start_, fill_, order_, counted_;
    std::vector<char> moving_, ahead_;
};

// A scanner's buffers are reused from call to call: the period scan makes thousands. Each scan
// owns its scanners rather than keeping one per thread: a thread_local with a destructor is
// registered under the dynamic loader's lock on its first use, and `cutload predict` ingests while
// another thread opens the OpenCL device (PoCL loads LLVM, tens of ms holding that lock).
double least_roughness_over_phases(PhaseScan& scan, const PosRead* r, std::size_t n, double period_s, int phases,
                                   double offset) {
    double least = 1e300;
    if (scan.run(r, n, period_s, phases, offset, nullptr, &least, nullptr)) return least;
    for (int i = 0; i < phases; ++i) least = std::min(least, tick_roughness(r, n, period_s, period_s * (i + offset) / phases));
    return least;
}

double tracked_roughness(const PosRead* r, std::size_t n, double period_s, int phases) {
    PhaseScan scan;
    return tracked_roughness(scan, r, n, period_s, phases);
}

std::vector<Candidate> scan_periods(const PosRead* r, std::size_t n, double lo, double hi, double rel_step,
                                    std::size_t keep, int phases, unsigned threads) {
    std::vector<Candidate> all;
    for (double T = lo; T <= hi; T *= 1.0 + rel_step) all.push_back({T, 0.0});
    // The trial periods are independent: on a short stretch (256 phases each) the scan is most of
    // `cutload inspect`'s time, so a second core takes every other period where the caller allows
    // one. Each thread has its own scanner, and each value is the same as in one thread.
    auto evaluate = [&](std::size_t first, std::size_t stride) {
        PhaseScan scan;
        for (std::size_t i = first; i < all.size(); i += stride)
            all[i].roughness = tracked_roughness(scan, r, n, all[i].period_s, phases);
    };
    const double work = double(all.size()) * double(n) * double(phases);
    std::thread second;
    std::exception_ptr failed;
    if (threads > 1 && work >= kParallelScanWork && std::thread::hardware_concurrency() > 1) {
        try {
            second = std::thread([&] {
                try {
                    evaluate(1, 2);
                } catch (...) {
                    failed = std::current_exception();
                }
            });
        } catch (const std::system_error&) {   // no thread to be had (a busy service): one does it all
        }
    }
    if (second.joinable()) {
        try {
            evaluate(0, 2);
        } catch (...) {
            second.join();
            throw;
        }
        second.join();
        if (failed) std::rethrow_exception(failed);
    } else {
        evaluate(0, 1);
    }
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

}  // namespace

void roughness_over_phases(const PosRead* r, std::size_t n, double period_s, int phases, double offset,
                           double* out, std::size_t* last_pairs) {
    PhaseScan scan;
    if (scan.run(r, n, period_s, phases, offset, out, nullptr, last_pairs)) return;
    for (int i = 0; i < phases; ++i) out[i] = tick_roughness(r, n, period_s, period_s * (i + offset) / phases, last_pairs);
}

double least_roughness_over_phases(const PosRead* r, std::size_t n, double period_s, int phases, double offset) {
    PhaseScan scan;
    return least_roughness_over_phases(scan, r, n, period_s, phases, offset);
}

UpdatePeriod estimate_update_period(const std::vector<PosRead>& reads, unsigned threads) {
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
        for (const Candidate& c : scan_periods(reads.data(), n_coarse, lo, hi, 2.5e-3, 5, phases, threads)) {
            const auto fine =
                scan_periods(reads.data(), n_fine, c.period_s * (1 - 5e-3), c.period_s * (1 + 5e-3), 2.5e-4, 1, phases,
                             threads);
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
    roughness_over_phases(r, n, period_s, phases, 0.0, rough.data(), &pairs);
    const double best = *std::min_element(rough.begin(), rough.end());
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
