// Steady segment, drift and zero offset of a measured straight cut (see calibrate.hpp and
// docs/compare_calibrate.md).
#include "force_model/calibrate.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <string>
#include <utility>

namespace cutload::force_model {

namespace {

using Vec3 = std::array<double, 3>;

// An idle revolution has less tooth-passing ripple than this share of the typical (90th
// percentile) ripple of the record; within such a run at either end, the revolutions whose ripple
// rises above kNoiseRise times the run's median are the first of the cut and are left out.
constexpr double kIdleShare = 0.2;
constexpr double kNoiseRise = 1.5;
// The first pass, before the drift is known, keeps revolutions within this multiple of the
// tolerance: enough for a drift of 20 % of the cutting force over the cut.
constexpr double kLooseFactor = 5.0;
// The air-gap estimate keeps this share of the tooth period clear of each edge of the gap (entry
// and exit transients, a spindle a little off its nominal speed) and needs a window of at least
// kMinAirWindow of the tooth period, and at least kMinSamplesPerTooth samples per tooth period.
constexpr double kAirMargin = 0.05;
constexpr double kMinAirWindow = 0.1;
constexpr double kMinSamplesPerTooth = 8;
// The spindle's actual speed is checked on stretches of kSegmentRevs revolutions, at most kMaxSegments.
constexpr double kSegmentRevs = 10;
constexpr double kMaxSegments = 64;

double norm(const Vec3& a) { return std::hypot(a[0], a[1], a[2]); }

Vec3 minus(const Vec3& a, const Vec3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }

double percentile(std::vector<double> v, double p) {
    const auto k = static_cast<std::size_t>(std::floor(p * static_cast<double>(v.size() - 1)));
    std::nth_element(v.begin(), v.begin() + static_cast<long>(k), v.end());
    return v[k];
}

Vec3 median_of(const std::vector<Vec3>& v, std::size_t a, std::size_t b) {
    Vec3 out{};
    std::vector<double> x;
    for (std::size_t ax = 0; ax < 3; ++ax) {
        x.clear();
        for (std::size_t j = a; j < b; ++j) x.push_back(v[j][ax]);
        out[ax] = percentile(x, 0.5);
    }
    return out;
}

// A record cut into whole revolutions of the nominal spindle speed.
struct Revolutions {
    const Measurement& m;
    double per_rev;   // samples per revolution
    std::size_t count;

    std::size_t first(std::size_t j) const { return static_cast<std::size_t>(std::llround(static_cast<double>(j) * per_rev)); }
    Vec3 mean(std::size_t i0, std::size_t i1) const {
        double s[3] = {0, 0, 0};
        for (std::size_t i = i0; i < i1; ++i) {
            s[0] += m.fx_N[i];
            s[1] += m.fy_N[i];
            s[2] += m.fz_N[i];
        }
        const double n = static_cast<double>(i1 - i0);
        return {s[0] / n, s[1] / n, s[2] / n};
    }
    double centre_s(std::size_t i0, std::size_t i1) const { return 0.5 * (m.t_s(i0) + m.t_s(i1 - 1)); }

    // Exactly whole revolutions [j0, j1): sample i stands for [i, i + 1) of the continuous sample
    // index, and a sample cut by a revolution's boundary counts with its share inside. When the
    // samples per revolution are not a whole number, whole-sample chunks let a part of the
    // tooth-passing ripple that changes from one revolution to the next into each mean; it biased
    // the drift found by several N/s.
    template <typename F>
    void weighted(std::size_t j0, std::size_t j1, F f) const {
        const double a = static_cast<double>(j0) * per_rev, b = static_cast<double>(j1) * per_rev;
        const auto i1 = std::min(m.size(), static_cast<std::size_t>(std::ceil(b)));
        for (auto i = static_cast<std::size_t>(std::floor(a)); i < i1; ++i) {
            const double w = std::min(static_cast<double>(i) + 1.0, b) - std::max(static_cast<double>(i), a);
            if (w > 0) f(i, w);
        }
    }
    Vec3 exact_mean(std::size_t j0, std::size_t j1) const {
        Vec3 s{};
        weighted(j0, j1, [&](std::size_t i, double w) {
            s[0] += w * m.fx_N[i];
            s[1] += w * m.fy_N[i];
            s[2] += w * m.fz_N[i];
        });
        const double n = static_cast<double>(j1 - j0) * per_rev;
        return {s[0] / n, s[1] / n, s[2] / n};
    }
    // Root-mean-square deviation from the mean within revolution j (all three axes).
    double ripple(std::size_t j, const Vec3& mean) const {
        double s = 0;
        weighted(j, j + 1, [&](std::size_t i, double w) {
            s += w * (std::pow(m.fx_N[i] - mean[0], 2) + std::pow(m.fy_N[i] - mean[1], 2) +
                      std::pow(m.fz_N[i] - mean[2], 2));
        });
        return std::sqrt(s / per_rev);
    }
    double exact_centre_s(std::size_t j0, std::size_t j1) const {
        return m.t0_s + (0.5 * static_cast<double>(j0 + j1) * per_rev - 0.5) / m.rate_Hz;
    }
    std::size_t first_sample(std::size_t j) const {
        return static_cast<std::size_t>(std::floor(static_cast<double>(j) * per_rev));
    }
    std::size_t end_sample(std::size_t j) const {
        return std::min(m.size(), static_cast<std::size_t>(std::ceil(static_cast<double>(j) * per_rev)));
    }
};

// Five-revolution moving mean against noise; it smears the ramps by two revolutions, which the
// trim after the search takes off again.
std::vector<Vec3> smooth5(const std::vector<Vec3>& v) {
    const std::size_t n = v.size();
    std::vector<Vec3> out(n);
    for (std::size_t j = 0; j < n; ++j) {
        const std::size_t a = j >= 2 ? j - 2 : 0, b = std::min(n, j + 3);
        Vec3 s{};
        for (std::size_t i = a; i < b; ++i)
            for (std::size_t ax = 0; ax < 3; ++ax) s[ax] += v[i][ax];
        for (auto& x : s) x /= static_cast<double>(b - a);
        out[j] = s;
    }
    return out;
}

// Longest run in [a, b) whose smoothed value stays within tol_N of centre.
std::pair<std::size_t, std::size_t> longest_run(const std::vector<Vec3>& smooth, std::size_t a, std::size_t b,
                                                const Vec3& centre, double tol_N) {
    std::size_t s0 = a, s1 = a;
    for (std::size_t j = a; j < b;) {
        std::size_t k = j;
        while (k < b && norm(minus(smooth[k], centre)) <= tol_N) ++k;
        if (k - j > s1 - s0) s0 = j, s1 = k;
        j = k + 1;
    }
    return {s0, s1};
}

// Robust: for the first pass, whose run may still hold a ramp revolution at either end.
std::array<double, 3> robust_slope_over(const std::vector<double>& t, const std::vector<Vec3>& v, std::size_t a,
                                        std::size_t b) {
    return robust_slope_per_s(std::vector<double>(t.begin() + static_cast<long>(a), t.begin() + static_cast<long>(b)),
                              std::vector<Vec3>(v.begin() + static_cast<long>(a), v.begin() + static_cast<long>(b)));
}

// Least squares: for a window known to be steady, where it has about half the variance. Empty
// when the slope does not stand out from the scatter of the points (drift_significant).
std::optional<Vec3> slope_over(const std::vector<double>& t, const std::vector<Vec3>& v, std::size_t a, std::size_t b) {
    if (b - a < 3) return std::nullopt;
    const double n = static_cast<double>(b - a);
    double tm = 0;
    Vec3 vm{};
    for (std::size_t j = a; j < b; ++j) {
        tm += t[j] / n;
        for (std::size_t ax = 0; ax < 3; ++ax) vm[ax] += v[j][ax] / n;
    }
    double stt = 0;
    Vec3 stv{};
    for (std::size_t j = a; j < b; ++j) {
        stt += (t[j] - tm) * (t[j] - tm);
        for (std::size_t ax = 0; ax < 3; ++ax) stv[ax] += (t[j] - tm) * (v[j][ax] - vm[ax]);
    }
    if (!(stt > 0)) return std::nullopt;
    Vec3 slope{}, residual{}, standard_error{};
    for (std::size_t ax = 0; ax < 3; ++ax) slope[ax] = stv[ax] / stt;
    for (std::size_t j = a; j < b; ++j)
        for (std::size_t ax = 0; ax < 3; ++ax)
            residual[ax] += std::pow(v[j][ax] - vm[ax] - slope[ax] * (t[j] - tm), 2) / (n - 2);
    for (std::size_t ax = 0; ax < 3; ++ax) standard_error[ax] = std::sqrt(residual[ax] / stt);
    if (!drift_significant(slope, standard_error)) return std::nullopt;
    return slope;
}

// Samples folded over one tooth period: per bin of phase, the sums of the samples and their squares.
struct Fold {
    std::vector<Vec3> sum, sq;
    std::vector<double> count;

    std::size_t bins() const { return count.size(); }
    Vec3 mean(std::size_t b) const { return {sum[b][0] / count[b], sum[b][1] / count[b], sum[b][2] / count[b]}; }
};

// Folds [i0, i1), drift removed about t_c, phase 0 at sample `origin`; empty if a bin gets fewer than
// two samples.
std::optional<Fold> fold(const Measurement& m, std::size_t origin, std::size_t i0, std::size_t i1, double per_tooth,
                         std::size_t bins, const Vec3& drift_N_per_s, double t_c) {
    Fold f{std::vector<Vec3>(bins), std::vector<Vec3>(bins), std::vector<double>(bins, 0.0)};
    const float* ch[3] = {m.fx_N.data(), m.fy_N.data(), m.fz_N.data()};
    for (std::size_t i = i0; i < i1; ++i) {
        const double phase = std::fmod(static_cast<double>(i - origin) / per_tooth, 1.0);
        const std::size_t b = std::min(bins - 1, static_cast<std::size_t>(phase * static_cast<double>(bins)));
        const double dt = m.t_s(i) - t_c;
        for (std::size_t ax = 0; ax < 3; ++ax) {
            const double x = ch[ax][i] - drift_N_per_s[ax] * dt;
            f.sum[b][ax] += x;
            f.sq[b][ax] += x * x;
        }
        f.count[b] += 1;
    }
    for (double c : f.count)
        if (c < 2) return std::nullopt;
    return f;
}

// The flattest stretch of a fold, `width` bins wide (circular): with air between tooth passes, the air.
struct AirWindow {
    Vec3 sum{};          // of the samples in the window
    double samples = 0;
    double spread = 0;   // variance of the bin means across the window (three axes summed)
    double within = 0;   // mean variance of the samples within a bin of the window (three axes summed)
};

AirWindow flattest(const Fold& f, std::size_t width) {
    const std::size_t bins = f.bins();
    // Circular prefix sums of the bin means and of their squares: every window's spread in O(bins).
    std::vector<double> squares(2 * bins + 1, 0.0);
    std::vector<Vec3> means(2 * bins + 1);
    for (std::size_t k = 0; k < 2 * bins; ++k) {
        const Vec3 w = f.mean(k % bins);
        squares[k + 1] = squares[k] + w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
        for (std::size_t ax = 0; ax < 3; ++ax) means[k + 1][ax] = means[k][ax] + w[ax];
    }
    const double n = static_cast<double>(width);
    std::size_t best = 0;
    double best_spread = std::numeric_limits<double>::infinity();
    for (std::size_t b = 0; b < bins; ++b) {
        double s = (squares[b + width] - squares[b]) / n;
        for (std::size_t ax = 0; ax < 3; ++ax) s -= std::pow((means[b + width][ax] - means[b][ax]) / n, 2);
        if (s < best_spread) best_spread = s, best = b;
    }
    AirWindow w;
    w.spread = std::max(0.0, best_spread);
    for (std::size_t k = 0; k < width; ++k) {
        const std::size_t b = (best + k) % bins;
        for (std::size_t ax = 0; ax < 3; ++ax) {
            w.within += (f.sq[b][ax] - f.sum[b][ax] * f.sum[b][ax] / f.count[b]) / (f.count[b] - 1) / n;
            w.sum[ax] += f.sum[b][ax];
        }
        w.samples += f.count[b];
    }
    return w;
}

// The circular shift s (bins, sub-bin by a parabola through the peak, in (-bins/2, bins/2]) at which
// `later` best matches `ref`: later[b + s] ~ ref[b].
double shift_bins(const Fold& ref, const Fold& later) {
    const std::size_t bins = ref.bins();
    std::vector<double> c(bins, 0.0);
    for (std::size_t s = 0; s < bins; ++s)
        for (std::size_t b = 0; b < bins; ++b) {
            const Vec3 r = ref.mean(b), l = later.mean((b + s) % bins);
            c[s] += r[0] * l[0] + r[1] * l[1] + r[2] * l[2];
        }
    const auto top = static_cast<std::size_t>(std::max_element(c.begin(), c.end()) - c.begin());
    const double cm = c[(top + bins - 1) % bins], c0 = c[top], cp = c[(top + 1) % bins];
    const double curvature = cm - 2 * c0 + cp;
    double s = static_cast<double>(top) + (curvature < 0 ? std::clamp(0.5 * (cm - cp) / curvature, -0.5, 0.5) : 0.0);
    if (s > 0.5 * static_cast<double>(bins)) s -= static_cast<double>(bins);
    return s;
}

// Noise variance per axis of [i0, i1) from the median absolute difference of successive samples:
// where the tool is in air, and along the smooth stretches of the cut, a difference is noise alone.
// It does not depend on any fold, so it can tell a smeared fold from air.
Vec3 noise_variance(const Measurement& m, std::size_t i0, std::size_t i1) {
    Vec3 out{};
    const float* ch[3] = {m.fx_N.data(), m.fy_N.data(), m.fz_N.data()};
    std::vector<double> d;
    d.reserve(i1 - i0);
    for (std::size_t ax = 0; ax < 3; ++ax) {
        d.clear();
        for (std::size_t i = i0 + 1; i < i1; ++i) d.push_back(std::abs(double(ch[ax][i]) - ch[ax][i - 1]));
        // |difference| of two independent normal samples: median 0.6745 sqrt(2) sigma.
        out[ax] = std::pow(percentile(d, 0.5) / (0.6745 * std::sqrt(2.0)), 2);
    }
    return out;
}

// The zero offset at t_c from the air between tooth passes of [i0, i1), folded over one tooth
// period. A spindle a little off its nominal speed moves the waveform along the fold as time goes on,
// and one fold of a long window would smear the air: stretches of the window are matched against a
// reference fold (the first stretch, then the whole window), and the line through their shifts gives
// the actual tooth period. The estimate is accepted only if the air is as flat, and as quiet within
// each bin, as the record's noise makes it.
std::optional<Vec3> zero_from_tooth_gaps(const Measurement& m, std::size_t i0, std::size_t i1, double per_rev,
                                         int flutes, double air_fraction, const Vec3& drift_N_per_s, double t_c) {
    if (flutes < 1) return std::nullopt;
    double per_tooth = per_rev / flutes;
    if (per_tooth < kMinSamplesPerTooth || air_fraction - 2 * kAirMargin < kMinAirWindow) return std::nullopt;
    const auto bins = static_cast<std::size_t>(std::min(360.0, std::floor(per_tooth)));
    const auto width = static_cast<std::size_t>(std::floor((air_fraction - 2 * kAirMargin) * static_cast<double>(bins)));
    if (width < 2) return std::nullopt;
    const double span = static_cast<double>(i1 - i0), nb = static_cast<double>(bins);
    const auto segments = static_cast<std::size_t>(std::min(kMaxSegments, std::floor(span / (kSegmentRevs * per_rev))));
    auto segment = [&](std::size_t k) {
        return std::pair<std::size_t, std::size_t>{
            i0 + static_cast<std::size_t>(std::llround(span * static_cast<double>(k) / static_cast<double>(segments))),
            i0 + static_cast<std::size_t>(std::llround(span * static_cast<double>(k + 1) / static_cast<double>(segments)))};
    };
    for (int pass = 0; pass < 2 && segments >= 4; ++pass) {
        const auto [r0, r1] = pass == 0 ? segment(0) : std::pair<std::size_t, std::size_t>{i0, i1};
        const auto ref = fold(m, i0, r0, r1, per_tooth, bins, drift_N_per_s, t_c);
        if (!ref) return std::nullopt;
        double st = 0, ss = 0, stt = 0, sts = 0, last = 0;   // least squares of shift (bins) on time (tooth periods)
        for (std::size_t k = 0; k < segments; ++k) {
            const auto [a, b] = segment(k);
            const auto part = fold(m, i0, a, b, per_tooth, bins, drift_N_per_s, t_c);
            if (!part) return std::nullopt;
            double shift = shift_bins(*ref, *part);
            if (k > 0) shift += nb * std::round((last - shift) / nb);   // unwrap: stretches move little
            last = shift;
            const double teeth = 0.5 * static_cast<double>(a + b - 2 * i0) / per_tooth;
            st += teeth;
            ss += shift;
            stt += teeth * teeth;
            sts += teeth * shift;
        }
        const double n = static_cast<double>(segments);
        const double slope = (sts - st * ss / n) / (stt - st * st / n);   // bins per tooth period
        per_tooth *= 1 + slope / nb;   // the waveform arrives later and later: a longer period
    }
    const auto whole = fold(m, i0, i0, i1, per_tooth, bins, drift_N_per_s, t_c);
    if (!whole) return std::nullopt;
    const AirWindow w = flattest(*whole, width);
    const Vec3 var = noise_variance(m, i0, i1);
    const double noise_var = var[0] + var[1] + var[2];
    if (!(w.spread <= 4 * noise_var * width / w.samples + 1e-12 && w.within <= 2 * noise_var + 1e-12)) return std::nullopt;
    return Vec3{w.sum[0] / w.samples, w.sum[1] / w.samples, w.sum[2] / w.samples};
}

[[noreturn]] void no_steady_cut(const Measurement& mm, const SteadyOptions& opt, std::size_t found) {
    throw SteadyError(fmt::format("{}: no steady cut: the longest run of revolutions within {:g} % of the median "
                                  "cutting force (drift removed) is {} (at least {} needed); give the steady window",
                                  mm.source, 100 * opt.tolerance, found, opt.min_revolutions),
                      SteadyError::Need::Window);
}

SteadyForce robust_steady(const Revolutions& r, const SteadyOptions& opt) {
    const Measurement& mm = r.m;
    const std::size_t revs = r.count;
    std::vector<Vec3> mean(revs);
    std::vector<double> ripple(revs), t(revs);
    for (std::size_t j = 0; j < revs; ++j) {
        mean[j] = r.exact_mean(j, j + 1);
        t[j] = r.exact_centre_s(j, j + 1);
        ripple[j] = r.ripple(j, mean[j]);
    }
    const double typical = percentile(ripple, 0.9);
    if (!(typical > 0)) throw MeasurementError(mm.source + ": the force never changes: no cut found");

    // Idle revolutions at each end, less the first ones of the cut and one revolution of margin.
    auto idle_run = [&](bool at_start) {
        auto rev = [&](std::size_t k) { return at_start ? k : revs - 1 - k; };
        std::size_t n = 0;
        while (n < revs && ripple[rev(n)] < kIdleShare * typical) ++n;
        if (n == 0) return std::size_t{0};
        std::vector<double> run;
        for (std::size_t k = 0; k < n; ++k) run.push_back(ripple[rev(k)]);
        const double noise = percentile(run, 0.5);
        while (n > 0 && ripple[rev(n - 1)] > kNoiseRise * noise) --n;
        return n > 1 ? n - 1 : std::size_t{0};
    };
    const std::size_t lead = idle_run(true);
    const std::size_t tail = lead >= revs ? 0 : std::min(idle_run(false), revs - lead);
    std::size_t c0 = revs, c1 = 0;   // cutting revolutions [c0, c1)
    for (std::size_t j = lead; j < revs - tail; ++j)
        if (ripple[j] >= opt.threshold * typical) c0 = std::min(c0, j), c1 = j + 1;
    if (c0 >= c1) throw MeasurementError(mm.source + ": no cut found (no revolution with tooth-passing ripple)");

    // Idle levels, and the drift between them when there is idle recording on both sides.
    auto idle_level = [&](std::size_t j0, std::size_t j1) {
        return std::pair<Vec3, double>{r.exact_mean(j0, j1), r.exact_centre_s(j0, j1)};
    };
    std::optional<std::pair<Vec3, double>> lead_level, tail_level;
    if (lead > 0) lead_level = idle_level(0, lead);
    if (tail > 0) tail_level = idle_level(revs - tail, revs);
    ZeroLine zero;
    if (opt.zero_N) {
        zero.source = ZeroSource::Given;
        zero.zero_N = *opt.zero_N;
        zero.t_s = mm.t_s(0);
    } else if (lead_level) {
        zero.source = ZeroSource::LeadIn;
        std::tie(zero.zero_N, zero.t_s) = *lead_level;
    } else if (tail_level) {
        zero.source = ZeroSource::IdleTail;
        std::tie(zero.zero_N, zero.t_s) = *tail_level;
    }
    // Drift between the idle stretches, if it stands out from the scatter of their revolution means.
    bool idle_drift_known = false;
    if (lead_level && tail_level && tail_level->second > lead_level->second) {
        idle_drift_known = true;
        Vec3 slope{}, scatter{}, standard_error{};
        for (std::size_t ax = 0; ax < 3; ++ax)
            slope[ax] = (tail_level->first[ax] - lead_level->first[ax]) / (tail_level->second - lead_level->second);
        if (lead + tail >= 3) {
            for (std::size_t j = 0; j < revs; ++j) {
                const auto* level = j < lead ? &*lead_level : j >= revs - tail ? &*tail_level : nullptr;
                if (!level) continue;
                for (std::size_t ax = 0; ax < 3; ++ax)
                    scatter[ax] += std::pow(mean[j][ax] - level->first[ax], 2) / static_cast<double>(lead + tail - 2);
            }
            for (std::size_t ax = 0; ax < 3; ++ax)
                standard_error[ax] = std::sqrt(scatter[ax] * (1.0 / static_cast<double>(lead) + 1.0 / static_cast<double>(tail))) /
                                     (tail_level->second - lead_level->second);
        }
        if (lead + tail < 3 || drift_significant(slope, standard_error)) {
            zero.drift_source = DriftSource::Idle;
            zero.drift_N_per_s = slope;
        }
    }
    // Revolution means less the zero as far as it is known (0 when it is not: then the scale of the
    // tolerance includes the offset, which is small beside a cutting force).
    std::vector<Vec3> level(revs);
    for (std::size_t j = 0; j < revs; ++j) level[j] = minus(mean[j], zero.at(t[j]));

    std::size_t s0 = 0, s1 = 0;   // steady revolutions [s0, s1)
    SteadyForce out;
    out.window_given = opt.t_start_s || opt.t_end_s;
    if (out.window_given) {
        const double a = opt.t_start_s.value_or(mm.t_s(0)), b = opt.t_end_s.value_or(mm.t_s(mm.size() - 1));
        if (!(b > a))
            throw MeasurementError(fmt::format("{}: the steady window [{:g}, {:g}] s ends before it starts", mm.source, a, b));
        auto rev_at = [&](double time) { return (time - mm.t0_s) * mm.rate_Hz / r.per_rev; };
        s0 = static_cast<std::size_t>(std::clamp(std::ceil(rev_at(a)), 0.0, static_cast<double>(revs)));
        s1 = static_cast<std::size_t>(std::clamp(std::floor(rev_at(b)), 0.0, static_cast<double>(revs)));
        if (s1 <= s0)
            throw MeasurementError(fmt::format("{}: no whole revolution in the steady window [{:g}, {:g}] s; the record "
                                               "covers [{:g}, {:g}] s",
                                               mm.source, a, b, mm.t_s(0), mm.t_s(mm.size() - 1)));
        if (!idle_drift_known)
            if (const auto slope = slope_over(t, level, s0, s1)) {
                zero.drift_source = DriftSource::Cut;
                zero.drift_N_per_s = *slope;
            }
    } else {
        // First pass, drift unknown: a loose tolerance finds the bulk of the steady cut.
        const Vec3 m1 = median_of(level, c0, c1);
        const auto [r0, r1] = longest_run(smooth5(level), c0, c1, m1, kLooseFactor * opt.tolerance * norm(m1));
        if (r1 - r0 < 2) no_steady_cut(mm, opt, r1 - r0);
        // Second pass, drift removed, at the tolerance.
        std::vector<Vec3> flat = level;
        if (!idle_drift_known) {
            const Vec3 slope = robust_slope_over(t, level, r0, r1);
            const double t_mid = 0.5 * (t[r0] + t[r1 - 1]);
            for (std::size_t j = 0; j < revs; ++j)
                for (std::size_t ax = 0; ax < 3; ++ax) flat[j][ax] -= slope[ax] * (t[j] - t_mid);
        }
        const Vec3 m2 = median_of(flat, r0, r1);
        std::tie(s0, s1) = longest_run(smooth5(flat), c0, c1, m2, opt.tolerance * norm(m2));
        if (s1 - s0 > 4) s0 += 2, s1 -= 2;
        if (s1 - s0 < static_cast<std::size_t>(opt.min_revolutions)) no_steady_cut(mm, opt, s1 - s0);
        // The trend over the final window alone: no ramp revolution left in it.
        if (!idle_drift_known)
            if (const auto slope = slope_over(t, mean, s0, s1)) {
                zero.drift_source = DriftSource::Cut;
                zero.drift_N_per_s = *slope;
            }
    }

    const std::size_t i0 = r.first_sample(s0), i1 = r.end_sample(s1);
    const double t_c = r.exact_centre_s(s0, s1);
    if (zero.source == ZeroSource::None) {
        const auto z = zero_from_tooth_gaps(mm, i0, i1, r.per_rev, opt.flutes, opt.air_fraction, zero.drift_N_per_s, t_c);
        if (!z) {
            const double per_tooth = opt.flutes > 0 ? r.per_rev / opt.flutes : 0.0;
            std::string why;
            if (!(opt.air_fraction > 0 && opt.flutes > 0))
                why = "no air between tooth passes to estimate it from (a slot, overlapping edges, or not a flat end mill)";
            else if (opt.air_fraction - 2 * kAirMargin < kMinAirWindow)
                why = fmt::format("too little air between tooth passes to estimate it from ({:.0f} % of each tooth "
                                  "period; {:.0f} % needed)",
                                  100 * opt.air_fraction, 100 * (kMinAirWindow + 2 * kAirMargin));
            else if (per_tooth < kMinSamplesPerTooth)
                why = fmt::format("{:.1f} samples per tooth period, too few to find the air between tooth passes "
                                  "(at least {:g})",
                                  per_tooth, kMinSamplesPerTooth);
            else
                why = "the air between tooth passes is not flat enough to read it from";
            throw SteadyError(fmt::format("{}: no zero offset: the record has no idle revolutions before or after "
                                          "the cut, and {}; give the zero offset",
                                          mm.source, why),
                              SteadyError::Need::Zero);
        }
        zero.source = ZeroSource::Estimated;
        zero.zero_N = *z;
        zero.t_s = t_c;
    }
    out.zero = zero;
    out.zero_N = zero.at(t_c);
    out.zeroed = true;
    out.mean_N = minus(r.exact_mean(s0, s1), out.zero_N);
    out.revolutions = static_cast<int>(s1 - s0);
    out.t_start_s = mm.t_s(i0);
    out.t_end_s = mm.t_s(i1 - 1);
    return out;
}

// The first detector, unchanged but for its report: levels relative to the first revolution.
SteadyForce first_revolution_steady(const Revolutions& r, const SteadyOptions& opt) {
    const Measurement& mm = r.m;
    const std::size_t revs = r.count;
    SteadyForce out;
    std::size_t s0 = 0, s1 = 0;   // steady revolutions [s0, s1)
    std::vector<Vec3> rev(revs);
    for (std::size_t j = 0; j < revs; ++j) rev[j] = r.mean(r.first(j), r.first(j + 1));
    auto dist = [](const Vec3& a, const Vec3& b) { return norm(minus(a, b)); };
    out.window_given = opt.t_start_s || opt.t_end_s;
    if (out.window_given) {
        const double a = opt.t_start_s.value_or(mm.t_s(0)), b = opt.t_end_s.value_or(mm.t_s(mm.size() - 1));
        auto rev_at = [&](double t) { return (t - mm.t0_s) * mm.rate_Hz / r.per_rev; };
        s0 = static_cast<std::size_t>(std::max(0.0, std::ceil(rev_at(a))));
        s1 = static_cast<std::size_t>(std::clamp(std::floor(rev_at(b)), 0.0, static_cast<double>(revs)));
        if (s1 <= s0)
            throw MeasurementError(fmt::format("{}: no whole revolution in the steady window [{:g}, {:g}] s",
                                               mm.source, a, b));
    } else {
        std::vector<double> level(revs);
        for (std::size_t j = 0; j < revs; ++j) level[j] = dist(rev[j], rev[0]);
        const double top = *std::max_element(level.begin(), level.end());
        if (top <= 0) throw MeasurementError(mm.source + ": the force never changes: no cut found");
        std::size_t c0 = revs, c1 = 0;
        for (std::size_t j = 0; j < revs; ++j)
            if (level[j] > opt.threshold * top) c0 = std::min(c0, j), c1 = j + 1;
        std::vector<double> cutting(level.begin() + static_cast<long>(c0), level.begin() + static_cast<long>(c1));
        const double median = percentile(cutting, 0.5);
        std::vector<double> smooth(revs);
        for (std::size_t j = 0; j < revs; ++j) {
            const std::size_t a = j >= 2 ? j - 2 : 0, b = std::min(revs, j + 3);
            double sum = 0;
            for (std::size_t i = a; i < b; ++i) sum += level[i];
            smooth[j] = sum / static_cast<double>(b - a);
        }
        for (std::size_t j = c0; j < c1;) {
            std::size_t k = j;
            while (k < c1 && std::abs(smooth[k] - median) <= opt.tolerance * median) ++k;
            if (k - j > s1 - s0) s0 = j, s1 = k;
            j = k + 1;
        }
        if (s1 - s0 > 4) s0 += 2, s1 -= 2;
        if (s1 - s0 < static_cast<std::size_t>(opt.min_revolutions))
            throw SteadyError(fmt::format("{}: no steady cut: the longest run of revolutions within {:g} % of the median "
                                          "cutting force is {} (at least {} needed); give the steady window",
                                          mm.source, 100 * opt.tolerance, s1 - s0, opt.min_revolutions),
                              SteadyError::Need::Window);
    }
    // Zero offset from the revolutions before the cut started, with one revolution of margin.
    std::size_t idle_end = s0;
    if (!out.window_given) {
        const double top_level = dist(rev[s0], rev[0]);
        idle_end = 0;
        while (idle_end < s0 && dist(rev[idle_end], rev[0]) < 0.05 * top_level) ++idle_end;
    }
    if (idle_end >= 2) {
        const std::size_t i1 = r.first(idle_end - 1);
        out.zero.source = ZeroSource::LeadIn;
        out.zero.zero_N = r.mean(0, i1);
        out.zero.t_s = r.centre_s(0, i1);
        out.zero_N = out.zero.zero_N;
        out.zeroed = true;
    }
    out.mean_N = minus(r.mean(r.first(s0), r.first(s1)), out.zero_N);
    out.revolutions = static_cast<int>(s1 - s0);
    out.t_start_s = mm.t_s(r.first(s0));
    out.t_end_s = mm.t_s(r.first(s1) - 1);
    return out;
}

}  // namespace

SteadyForce steady_mean_force(const Measurement& mm, double spindle_rpm, const SteadyOptions& opt) {
    if (!mm.tool_machine_axes) throw MeasurementError(mm.source + ": map the measurement to machine axes first");
    if (!(spindle_rpm > 0)) throw SpecError("spindle_rpm: must be > 0");
    const double per_rev = mm.rate_Hz * 60.0 / spindle_rpm;   // samples per revolution
    const auto revs = static_cast<std::size_t>(std::floor(static_cast<double>(mm.size()) / per_rev));
    if (revs < static_cast<std::size_t>(std::max(opt.min_revolutions, 1)))
        throw MeasurementError(fmt::format("{}: {} whole revolutions recorded at {:g} rpm; at least {} are needed",
                                           mm.source, revs, spindle_rpm, opt.min_revolutions));
    if (per_rev < 1)
        throw MeasurementError(fmt::format("{}: {:g} samples per revolution at {:g} rpm: the record is sampled too "
                                           "slowly for revolution means",
                                           mm.source, per_rev, spindle_rpm));
    const Revolutions r{mm, per_rev, revs};
    return opt.detector == SteadyDetector::FirstRevolution ? first_revolution_steady(r, opt) : robust_steady(r, opt);
}

}  // namespace cutload::force_model
