// Prediction against measurement (see compare.hpp and docs/compare_calibrate.md).
#include "force_model/compare.hpp"

#include "textio/csv.hpp"
#include "textio/number.hpp"
#include "textio/text.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <unsupported/Eigen/FFT>

#include <algorithm>
#include <cmath>
#include <complex>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <numbers>
#include <string_view>

namespace cutload::force_model {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Linear interpolation of a time-sorted prediction at increasing query times (one forward cursor).
class PredictionSampler {
public:
    explicit PredictionSampler(const std::vector<ForceSample>& s) : s_(s) {}

    struct Value {
        double f[3];
        double angle_deg;
        std::int32_t block;
    };

    Value at(double t_s) {
        while (i_ + 2 < s_.size() && s_[i_ + 1].t_s <= t_s) ++i_;
        const ForceSample& a = s_[i_];
        const ForceSample& b = s_[std::min(i_ + 1, s_.size() - 1)];
        const double span = b.t_s - a.t_s;
        const double u = span > 0 ? std::clamp((t_s - a.t_s) / span, 0.0, 1.0) : 0.0;
        auto lerp = [u](double x, double y) { return x + u * (y - x); };
        return {{lerp(a.fx_N, b.fx_N), lerp(a.fy_N, b.fy_N), lerp(a.fz_N, b.fz_N)},
                lerp(a.spindle_angle_deg, b.spindle_angle_deg),
                u < 0.5 ? a.block : b.block};
    }

private:
    const std::vector<ForceSample>& s_;
    std::size_t i_ = 0;
};

void require_prediction(const PredictedTrace& p) {
    if (p.samples.size() < 2) throw MeasurementError("the prediction has fewer than two rows");
}

void require_mapped(const Measurement& m) {
    if (!m.tool_machine_axes)
        throw MeasurementError(m.source + ": map the measurement to tool / machine axes before comparing");
    if (m.size() < 2) throw MeasurementError(m.source + ": fewer than two samples");
}

// One biquad section in transposed direct form II.
struct Biquad {
    double b0, b1, b2, a1, a2;
    double z1 = 0, z2 = 0;

    void settle(double x) {   // state of a long constant input x (the DC gain is 1)
        z1 = (1 - b0) * x;
        z2 = (b2 - a2) * x;
    }
    double step(double x) {
        const double y = b0 * x + z1;
        z1 = b1 * x - a1 * y + z2;
        z2 = b2 * x - a2 * y;
        return y;
    }
};

// Butterworth low-pass as cascaded second-order sections: bilinear transform prewarped at the
// cut-off, section Q values 1 / (2 cos((2k + 1) pi / (2 order))).
std::vector<Biquad> butterworth(double rate_Hz, double cutoff_Hz, int order) {
    const double w0 = 2 * std::numbers::pi * cutoff_Hz / rate_Hz;
    const double cw = std::cos(w0), sw = std::sin(w0);
    std::vector<Biquad> sections;
    for (int k = 0; k < order / 2; ++k) {
        const double q = 1.0 / (2 * std::cos((2 * k + 1) * std::numbers::pi / (2.0 * order)));
        const double alpha = sw / (2 * q), a0 = 1 + alpha;
        sections.push_back({(1 - cw) / 2 / a0, (1 - cw) / a0, (1 - cw) / 2 / a0, -2 * cw / a0, (1 - alpha) / a0});
    }
    return sections;
}

void run_filter(std::vector<double>& x, std::vector<Biquad> sections) {
    for (Biquad& s : sections) {
        s.settle(x.front());
        for (double& v : x) v = s.step(v);
    }
}

void remove_mean(std::vector<double>& x) {
    double s = 0;
    for (double v : x) s += v;
    s /= static_cast<double>(x.size());
    for (double& v : x) v -= s;
}

// Summed over axes: c(L) = sum_i m_i p_{i+L}, for every lag L in [-(n_m - 1), n_p - 1]; index L + n_m - 1.
std::vector<double> full_correlation(const std::vector<double> (&m)[3], const std::vector<double> (&p)[3]) {
    const std::size_t nm = m[0].size(), np = p[0].size();
    std::size_t n = 1;
    while (n < nm + np) n <<= 1;
    Eigen::FFT<double> fft;
    std::vector<std::complex<double>> acc(n), fa, fb;
    std::vector<double> a(n), b(n);
    for (int ax = 0; ax < 3; ++ax) {
        std::fill(a.begin(), a.end(), 0.0);
        std::fill(b.begin(), b.end(), 0.0);
        std::copy(m[ax].begin(), m[ax].end(), a.begin());
        std::copy(p[ax].begin(), p[ax].end(), b.begin());
        fft.fwd(fa, a);
        fft.fwd(fb, b);
        for (std::size_t k = 0; k < n; ++k) acc[k] += std::conj(fa[k]) * fb[k];
    }
    std::vector<double> c;
    fft.inv(c, acc);
    std::vector<double> out(nm + np - 1);
    for (std::size_t j = 0; j < out.size(); ++j) {
        const long lag = static_cast<long>(j) - static_cast<long>(nm - 1);
        out[j] = c[static_cast<std::size_t>(lag >= 0 ? lag : static_cast<long>(n) + lag)];
    }
    return out;
}

// Sums over the overlap at one lag, summed over the axes, each axis centred on its overlap mean.
struct LagSum {
    double centred_cross = 0, centred_mm = 0, centred_pp = 0;
};

double pearson(const LagSum& s) {
    return s.centred_mm > 0 && s.centred_pp > 0 ? s.centred_cross / std::sqrt(s.centred_mm * s.centred_pp) : 0.0;
}

LagSum lag_sum(const std::vector<double> (&m)[3], const std::vector<double> (&p)[3], long lag) {
    const long nm = static_cast<long>(m[0].size()), np = static_cast<long>(p[0].size());
    const long i0 = std::max(0L, -lag), i1 = std::min(nm, np - lag);
    LagSum s;
    if (i1 <= i0) return s;
    const double n = static_cast<double>(i1 - i0);
    for (int ax = 0; ax < 3; ++ax) {
        double sa = 0, sb = 0, sab = 0, saa = 0, sbb = 0;
        for (long i = i0; i < i1; ++i) {
            const double a = m[ax][static_cast<std::size_t>(i)], b = p[ax][static_cast<std::size_t>(i + lag)];
            sa += a;
            sb += b;
            sab += a * b;
            saa += a * a;
            sbb += b * b;
        }
        s.centred_cross += sab - sa * sb / n;
        s.centred_mm += saa - sa * sa / n;
        s.centred_pp += sbb - sb * sb / n;
    }
    return s;
}

AxisMetrics axis_metrics(const std::vector<double>& pred, const std::vector<double>& meas) {
    AxisMetrics a;
    const double n = static_cast<double>(pred.size());
    double se = 0, sse = 0, sp = 0, sm = 0, spp = 0, smm = 0, spm = 0;
    double mmin = std::numeric_limits<double>::infinity(), mmax = -mmin;
    for (std::size_t i = 0; i < pred.size(); ++i) {
        const double e = pred[i] - meas[i];
        se += e;
        sse += e * e;
        sp += pred[i];
        sm += meas[i];
        spp += pred[i] * pred[i];
        smm += meas[i] * meas[i];
        spm += pred[i] * meas[i];
        mmin = std::min(mmin, meas[i]);
        mmax = std::max(mmax, meas[i]);
        a.peak_measured_N = std::max(a.peak_measured_N, std::abs(meas[i]));
        a.peak_predicted_N = std::max(a.peak_predicted_N, std::abs(pred[i]));
    }
    a.mean_error_N = se / n;
    a.rmse_N = std::sqrt(sse / n);
    a.nrmse = mmax > mmin ? a.rmse_N / (mmax - mmin) : kNaN;
    a.peak_error_N = a.peak_predicted_N - a.peak_measured_N;
    const double vp = spp - sp * sp / n, vm = smm - sm * sm / n;
    a.correlation = vp > 0 && vm > 0 ? (spm - sp * sm / n) / std::sqrt(vp * vm) : kNaN;
    return a;
}

struct Series {
    std::vector<double> t_s, angle_deg;
    std::vector<std::int32_t> block;
    std::vector<double> pred[4], meas[4];   // x, y, z, resultant

    std::size_t size() const { return t_s.size(); }
};

ScopeMetrics scope_metrics(const Series& s, const std::vector<std::size_t>& idx, std::string scope) {
    ScopeMetrics m;
    m.scope = std::move(scope);
    m.samples = idx.size();
    m.t_start_s = s.t_s[idx.front()];
    m.t_end_s = s.t_s[idx.back()];
    std::vector<double> p(idx.size()), q(idx.size());
    for (int ax = 0; ax < 4; ++ax) {
        for (std::size_t k = 0; k < idx.size(); ++k) {
            p[k] = s.pred[ax][idx[k]];
            q[k] = s.meas[ax][idx[k]];
        }
        m.axes[ax] = axis_metrics(p, q);
    }
    return m;
}

// Means over whole periods of spindle angle; the last, incomplete period is dropped.
Series period_means(const Series& s, double period_deg) {
    Series out;
    std::size_t begin = 0;
    auto period_of = [&](std::size_t i) {
        return static_cast<long>(std::floor(std::abs(s.angle_deg[i] - s.angle_deg[0]) / period_deg));
    };
    for (std::size_t i = 1; i <= s.size(); ++i) {
        if (i < s.size() && period_of(i) == period_of(begin)) continue;
        if (i == s.size()) break;
        const double n = static_cast<double>(i - begin);
        double t = 0, p[4] = {0, 0, 0, 0}, m[4] = {0, 0, 0, 0};
        for (std::size_t j = begin; j < i; ++j) {
            t += s.t_s[j];
            for (int ax = 0; ax < 3; ++ax) {
                p[ax] += s.pred[ax][j];
                m[ax] += s.meas[ax][j];
            }
        }
        out.t_s.push_back(t / n);
        out.angle_deg.push_back(s.angle_deg[begin]);
        out.block.push_back(s.block[(begin + i) / 2]);
        for (int ax = 0; ax < 3; ++ax) {
            out.pred[ax].push_back(p[ax] / n);
            out.meas[ax].push_back(m[ax] / n);
        }
        begin = i;
    }
    return out;
}

void fill_resultants(Series& s) {
    s.pred[3].resize(s.size());
    s.meas[3].resize(s.size());
    for (std::size_t i = 0; i < s.size(); ++i) {
        s.pred[3][i] = std::hypot(s.pred[0][i], s.pred[1][i], s.pred[2][i]);
        s.meas[3][i] = std::hypot(s.meas[0][i], s.meas[1][i], s.meas[2][i]);
    }
}

using textio::csv_field;

nlohmann::json number_or_null(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(); }

}  // namespace

const char* averaging_name(Averaging a) {
    switch (a) {
        case Averaging::ToothPeriod: return "tooth";
        case Averaging::Revolution: return "revolution";
        case Averaging::None: break;
    }
    return "none";
}

PredictedTrace predicted_trace(const Prediction& p) {
    PredictedTrace t;
    t.samples = p.samples;
    t.block_names = p.block_names;
    std::stable_sort(t.samples.begin(), t.samples.end(), [](const auto& a, const auto& b) { return a.t_s < b.t_s; });
    return t;
}

PredictedTrace read_forces_csv(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw MeasurementError(textio::printable(path) + ": cannot open the predicted forces file");
    return read_forces_csv(in, path);
}

PredictedTrace read_predicted_forces(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw MeasurementError(textio::printable(path) + ": cannot open the predicted forces file");
    // FORCES.csv begins with its header's `t`; FORCES.bin with 0x89, which no text file starts with
    // (so a pipe can be told apart without reading it twice).
    if (in.peek() == 0x89) return read_forces_bin(in, path);
    return read_forces_csv(in, path);
}

PredictedTrace read_forces_csv(std::istream& in, const std::string& source) {
    const std::string shown = textio::printable(source);
    textio::CsvReader csv(in, shown);
    try {
        if (!csv.next()) throw MeasurementError(shown + ":1: empty file (expected the FORCES.csv header)");
        std::vector<std::string> header;
        for (std::size_t i = 0; i < csv.size(); ++i) header.emplace_back(csv[i]);
        auto column = [&](const char* name) {
            const auto it = std::find(header.begin(), header.end(), name);
            if (it == header.end())
                throw MeasurementError(fmt::format("{}:{}: no `{}` column (is this a FORCES.csv from cutload predict?)",
                                                   shown, csv.line(), name));
            return static_cast<std::size_t>(it - header.begin());
        };
        const std::size_t ct = column("t_s"), ca = column("spindle_angle_deg"), cb = column("block");
        const std::size_t cf[3] = {column("fx_N"), column("fy_N"), column("fz_N")};
        std::size_t need = std::max({ct, ca, cb, cf[0], cf[1], cf[2]});
        PredictedTrace t;
        t.source = shown;
        // The machine-axis triplet only counts whole: a file with part of it is read as one without.
        std::size_t cm[3] = {0, 0, 0};
        t.machine_axes = true;
        for (int k = 0; k < 3; ++k) {
            const char* name = k == 0 ? "fx_machine_N" : k == 1 ? "fy_machine_N" : "fz_machine_N";
            const auto it = std::find(header.begin(), header.end(), name);
            t.machine_axes = t.machine_axes && it != header.end();
            if (it != header.end()) cm[k] = static_cast<std::size_t>(it - header.begin());
        }
        if (t.machine_axes) need = std::max({need, cm[0], cm[1], cm[2]});
        // The tool axis too, read whole or not at all (as FORCES.bin's reader does).
        std::size_t ca3[3] = {0, 0, 0};
        bool tool_axis = true;
        for (int k = 0; k < 3; ++k) {
            const char* name = k == 0 ? "tool_axis_x" : k == 1 ? "tool_axis_y" : "tool_axis_z";
            const auto it = std::find(header.begin(), header.end(), name);
            tool_axis = tool_axis && it != header.end();
            if (it != header.end()) ca3[k] = static_cast<std::size_t>(it - header.begin());
        }
        if (tool_axis) need = std::max({need, ca3[0], ca3[1], ca3[2]});
        std::map<std::string, std::int32_t, std::less<>> blocks;
        while (csv.next()) {
            if (csv.size() <= need)
                throw MeasurementError(fmt::format("{}:{}: {} columns where the header has {}", shown, csv.line(), csv.size(),
                                                   header.size()));
            auto num = [&](std::size_t c) {
                const textio::ParsedNumber p = textio::parse_number(csv[c]);
                if (!p)
                    csv.fail(c, fmt::format("column {} ({}): {}", c + 1, header[c],
                                            textio::number_problem(csv[c], p.error == textio::NumberError::empty
                                                                               ? textio::NumberError::not_a_number
                                                                               : p.error)));
                return p.value;
            };
            // A force past float's range would be stored as infinity; no prediction gives one.
            auto force = [&](std::size_t c) {
                const double v = num(c);
                if (!(std::abs(v) <= 1e6))
                    csv.fail(c, fmt::format("column {} ({}): force {:g} N is beyond \u00b11e+06 N", c + 1, header[c], v));
                return static_cast<float>(v);
            };
            ForceSample s;
            s.t_s = num(ct);
            if (!(std::abs(s.t_s) <= 1e9)) csv.fail(ct, fmt::format("column {} (t_s): time {:g} s is beyond \u00b11e+09 s", ct + 1, s.t_s));
            s.spindle_angle_deg = num(ca);
            s.fx_N = force(cf[0]);
            s.fy_N = force(cf[1]);
            s.fz_N = force(cf[2]);
            if (t.machine_axes) {
                s.fx_machine_N = force(cm[0]);
                s.fy_machine_N = force(cm[1]);
                s.fz_machine_N = force(cm[2]);
            }
            if (tool_axis) {
                for (int k = 0; k < 3; ++k) {
                    const double v = num(ca3[k]);
                    if (!(std::abs(v) <= 1.001))
                        csv.fail(ca3[k], fmt::format("column {} ({}): {} is not a unit vector's component (beyond \u00b11.001)", ca3[k] + 1,
                                                     header[ca3[k]], v));
                }
                s.tool_axis_x = static_cast<float>(num(ca3[0]));
                s.tool_axis_y = static_cast<float>(num(ca3[1]));
                s.tool_axis_z = static_cast<float>(num(ca3[2]));
            }
            if (const std::string_view name = csv[cb]; !name.empty()) {
                auto it = blocks.find(name);
                if (it == blocks.end()) {
                    it = blocks.emplace(std::string(name), static_cast<std::int32_t>(t.block_names.size())).first;
                    t.block_names.emplace_back(name);
                }
                s.block = it->second;
            }
            if (!t.samples.empty() && s.t_s < t.samples.back().t_s)
                throw MeasurementError(fmt::format("{}:{}: time {} s goes back from {} s", shown, csv.line(), s.t_s,
                                                   t.samples.back().t_s));
            t.samples.push_back(s);
        }
        if (t.samples.size() < 2) throw MeasurementError(shown + ": fewer than two rows of predicted forces");
        return t;
    } catch (const textio::TextError& e) {
        throw MeasurementError(e.what());
    }
}

namespace {

void lowpass_in_place(std::vector<double>& x, double rate_Hz, double cutoff_Hz, int order) {
    if (!(cutoff_Hz > 0 && cutoff_Hz < 0.5 * rate_Hz))
        throw MeasurementError(fmt::format("low-pass cut-off {:g} Hz must be in (0, {:g}) Hz (half the sampling rate)",
                                           cutoff_Hz, 0.5 * rate_Hz));
    if (order < 2 || order % 2 != 0) throw MeasurementError("low-pass order must be even and at least 2");
    if (x.size() < 2) return;
    // Odd reflection about each end, about three time constants long, so the start-up transient
    // of each pass dies out in the padding.
    const std::size_t pad = std::min(x.size() - 1, static_cast<std::size_t>(std::ceil(3.0 * rate_Hz / cutoff_Hz)));
    const std::size_t n = x.size();
    std::vector<double> y(n + 2 * pad);
    for (std::size_t i = 0; i < pad; ++i) {
        y[i] = 2.0 * x[0] - x[pad - i];
        y[n + pad + i] = 2.0 * x[n - 1] - x[n - 2 - i];
    }
    std::copy(x.begin(), x.end(), y.begin() + static_cast<long>(pad));
    const std::vector<Biquad> sections = butterworth(rate_Hz, cutoff_Hz, order);
    run_filter(y, sections);
    std::reverse(y.begin(), y.end());
    run_filter(y, sections);
    std::reverse(y.begin(), y.end());
    std::copy(y.begin() + static_cast<long>(pad), y.begin() + static_cast<long>(pad + n), x.begin());
}

// Anti-aliased decimation for the coarse search: low-pass at 0.4 of the new rate, keep every factor-th.
std::vector<double> decimate(std::vector<double> x, double rate_Hz, std::size_t factor) {
    if (factor == 1) return x;
    lowpass_in_place(x, rate_Hz, 0.4 * rate_Hz / static_cast<double>(factor), 4);
    std::vector<double> out(x.size() / factor);
    for (std::size_t i = 0; i < out.size(); ++i) out[i] = x[i * factor];
    return out;
}

}  // namespace

void lowpass_zero_phase(std::vector<float>& x, double rate_Hz, double cutoff_Hz, int order) {
    std::vector<double> y(x.begin(), x.end());
    lowpass_in_place(y, rate_Hz, cutoff_Hz, order);
    std::copy(y.begin(), y.end(), x.begin());
}

double find_offset_s(const PredictedTrace& predicted, const Measurement& measured, double* score) {
    require_prediction(predicted);
    require_mapped(measured);
    const double fs = measured.rate_Hz;
    const double tp0 = predicted.samples.front().t_s, tp1 = predicted.samples.back().t_s;
    const auto np = static_cast<std::size_t>(std::floor((tp1 - tp0) * fs)) + 1;
    std::vector<double> m[3], p[3];
    const std::vector<float>* mf[3] = {&measured.fx_N, &measured.fy_N, &measured.fz_N};
    PredictionSampler sampler(predicted.samples);
    for (int ax = 0; ax < 3; ++ax) {
        m[ax].assign(mf[ax]->begin(), mf[ax]->end());
        p[ax].resize(np);
    }
    for (std::size_t k = 0; k < np; ++k) {
        const auto v = sampler.at(tp0 + static_cast<double>(k) / fs);
        for (int ax = 0; ax < 3; ++ax) p[ax][k] = v.f[ax];
    }
    // Tooth entries are near steps; unfiltered, the correlation peak is a sample or two wide and the
    // sub-sample phase outweighs the entry and exit that tell the tooth-period aliases apart.
    for (int ax = 0; ax < 3; ++ax) {
        remove_mean(m[ax]);
        remove_mean(p[ax]);
        lowpass_in_place(m[ax], fs, 0.05 * fs, 4);
        lowpass_in_place(p[ax], fs, 0.05 * fs, 4);
    }
    // Coarse: about 2 kHz, Pearson correlation at every lag with enough overlap. The
    // overlap's own means are removed at each lag (prefix sums), so air before or after the cut does
    // not pull the peak towards larger overlaps.
    const std::size_t factor = std::max<std::size_t>(1, static_cast<std::size_t>(std::floor(fs / 2000.0)));
    std::vector<double> mc[3], pc[3];
    for (int ax = 0; ax < 3; ++ax) {
        mc[ax] = decimate(m[ax], fs, factor);
        pc[ax] = decimate(p[ax], fs, factor);
    }
    if (mc[0].size() < 2 || pc[0].size() < 2)
        throw MeasurementError("the measurement or the prediction is too short to align (a few ms at least)");
    const std::vector<double> c = full_correlation(mc, pc);
    const long nmc = static_cast<long>(mc[0].size()), npc = static_cast<long>(pc[0].size());
    std::vector<double> sm[3], smm[3], sp[3], spp[3];   // prefix sums
    for (int ax = 0; ax < 3; ++ax) {
        auto prefix = [](const std::vector<double>& x, std::vector<double>& s1, std::vector<double>& s2) {
            s1.assign(x.size() + 1, 0.0);
            s2.assign(x.size() + 1, 0.0);
            for (std::size_t i = 0; i < x.size(); ++i) {
                s1[i + 1] = s1[i] + x[i];
                s2[i + 1] = s2[i] + x[i] * x[i];
            }
        };
        prefix(mc[ax], sm[ax], smm[ax]);
        prefix(pc[ax], sp[ax], spp[ax]);
    }
    const long min_overlap = std::max(2L, std::min(nmc, npc) / 2);
    std::vector<double> r(c.size(), -2.0);
    for (long j = 0; j < static_cast<long>(c.size()); ++j) {
        const long lag = j - (nmc - 1);
        const long i0 = std::max(0L, -lag), i1 = std::min(nmc, npc - lag);
        if (i1 - i0 < min_overlap) continue;
        const double n = static_cast<double>(i1 - i0);
        const auto a = static_cast<std::size_t>(i0), b = static_cast<std::size_t>(i1);
        const auto pa = static_cast<std::size_t>(i0 + lag), pb = static_cast<std::size_t>(i1 + lag);
        LagSum s;
        s.centred_cross = c[static_cast<std::size_t>(j)];
        for (int ax = 0; ax < 3; ++ax) {
            const double sum_m = sm[ax][b] - sm[ax][a], sum_p = sp[ax][pb] - sp[ax][pa];
            s.centred_cross -= sum_m * sum_p / n;
            s.centred_mm += smm[ax][b] - smm[ax][a] - sum_m * sum_m / n;
            s.centred_pp += spp[ax][pb] - spp[ax][pa] - sum_p * sum_p / n;
        }
        r[static_cast<std::size_t>(j)] = pearson(s);
    }
    // A steady cut is nearly periodic: lags a whole number of tooth periods apart correlate almost as
    // well, and at the coarse rate the sharp tooth-entry edges blur, so the coarse ranking of those
    // aliases is not reliable. Every coarse peak within 0.05 of the best (at most 64, best first)
    // goes to the full-rate search, which decides.
    std::vector<long> peaks;
    const double top = *std::max_element(r.begin(), r.end());
    for (std::size_t j = 0; j < r.size(); ++j) {
        const bool left = j == 0 || r[j] >= r[j - 1], right = j + 1 == r.size() || r[j] > r[j + 1];
        if (r[j] > -2.0 && r[j] >= top - 0.05 && left && right) peaks.push_back(static_cast<long>(j));
    }
    if (peaks.empty()) throw MeasurementError("the measurement and the prediction do not overlap enough to align");
    constexpr std::size_t kCandidates = 64;
    const std::size_t keep = std::min(kCandidates, peaks.size());
    std::partial_sort(peaks.begin(), peaks.begin() + static_cast<long>(keep), peaks.end(),
                      [&](long a, long b) { return r[static_cast<std::size_t>(a)] > r[static_cast<std::size_t>(b)]; });
    peaks.resize(keep);
    // Fine: full rate within one coarse sample of each candidate; a parabola through the best lag and
    // its neighbours gives the sub-sample peak and its height, and the highest peak wins (aliases
    // differ by less than an integer lag's sub-sample loss, so integer values cannot rank them).
    const long f = static_cast<long>(factor);
    double best_lag = 0, best_fine = -std::numeric_limits<double>::infinity();
    for (long j : peaks) {
        const long coarse_lag = j - (nmc - 1);
        long lag_here = coarse_lag * f;
        double v_here = -std::numeric_limits<double>::infinity();
        for (long lag = coarse_lag * f - f; lag <= coarse_lag * f + f; ++lag) {
            const double v = pearson(lag_sum(m, p, lag));
            if (v > v_here) v_here = v, lag_here = lag;
        }
        const double cm = pearson(lag_sum(m, p, lag_here - 1)), cp = pearson(lag_sum(m, p, lag_here + 1));
        const double curvature = cm - 2 * v_here + cp;
        const double frac = curvature < 0 ? std::clamp(0.5 * (cm - cp) / curvature, -0.5, 0.5) : 0.0;
        const double peak = v_here - 0.25 * (cm - cp) * frac;
        if (peak > best_fine) best_fine = peak, best_lag = static_cast<double>(lag_here) + frac;
    }
    if (score) *score = best_fine;
    return tp0 - measured.t0_s + best_lag / fs;
}

namespace {

// The zero offset of the compared samples (prediction time t_s): from the samples where the
// prediction is exactly zero (see CompareOptions::remove_zero), or given at the record's first
// sample (prediction time t_record_s).
ZeroLine zero_line(const std::vector<double>& t_s, const std::vector<float> (&mf)[3], const std::vector<float> (&pf)[3],
                   const CompareOptions& opt, double t_record_s) {
    constexpr std::size_t kMinAir = 100;
    // An air sample is kGuard samples from any cutting one: with an offset a fraction of a sample off,
    // the measured force at the edge of a tooth pass is already rising where the prediction is still 0.
    constexpr std::size_t kGuard = 2;
    std::vector<std::size_t> air;
    std::size_t first_cut = t_s.size(), last_cut = 0, last_cut_seen = 0;
    bool any_cut = false;
    const std::size_t n = t_s.size();
    auto cutting = [&](std::size_t i) { return pf[0][i] != 0 || pf[1][i] != 0 || pf[2][i] != 0; };
    for (std::size_t i = 0; i < n; ++i) {
        if (!cutting(i)) continue;
        first_cut = std::min(first_cut, i);
        last_cut = i;
    }
    for (std::size_t i = 0, next_cut = 0; i < n; ++i) {
        if (cutting(i)) {
            any_cut = true;
            last_cut_seen = i;
            continue;
        }
        if (next_cut <= i) {
            next_cut = i + 1;
            while (next_cut < n && !cutting(next_cut)) ++next_cut;
        }
        if ((!any_cut || i - last_cut_seen > kGuard) && (next_cut >= n || next_cut - i > kGuard)) air.push_back(i);
    }
    ZeroLine z;
    if (air.size() >= kMinAir) {
        std::size_t lead = 0, tail = 0;
        double tm = 0;
        for (std::size_t i : air) {
            lead += i < first_cut;
            tail += i > last_cut && first_cut < t_s.size();
            tm += t_s[i];
        }
        tm /= static_cast<double>(air.size());
        z.source = lead >= kMinAir ? ZeroSource::LeadIn : tail >= kMinAir ? ZeroSource::IdleTail : ZeroSource::Estimated;
        z.t_s = tm;
        double stt = 0;
        for (std::size_t i : air) stt += (t_s[i] - tm) * (t_s[i] - tm);
        const bool spread = t_s[air.back()] - t_s[air.front()] >= 0.5 * (t_s.back() - t_s.front()) && stt > 0;
        const double n_air = static_cast<double>(air.size());
        std::array<double, 3> slope{}, standard_error{};
        for (std::size_t ax = 0; ax < 3; ++ax) {
            double sf = 0, sff = 0, stf = 0;
            for (std::size_t i : air) {
                sf += mf[ax][i];
                sff += double(mf[ax][i]) * mf[ax][i];
                stf += (t_s[i] - tm) * mf[ax][i];
            }
            z.zero_N[ax] = sf / n_air;
            if (stt > 0) {
                slope[ax] = stf / stt;
                const double residual = std::max(0.0, sff - sf * sf / n_air - slope[ax] * slope[ax] * stt) / (n_air - 2);
                standard_error[ax] = std::sqrt(residual / stt);
            }
        }
        if (spread && drift_significant(slope, standard_error)) {
            z.drift_N_per_s = slope;
            z.drift_source = DriftSource::Idle;
        }
    }
    if (opt.zero_N) {
        z.source = ZeroSource::Given;
        z.zero_N = *opt.zero_N;
        z.t_s = t_record_s;
    }
    return z;
}

}  // namespace

Comparison compare(const PredictedTrace& predicted, const Measurement& measured, const CompareOptions& opt) {
    require_prediction(predicted);
    require_mapped(measured);
    if (opt.averaging == Averaging::ToothPeriod && opt.flutes < 1)
        throw MeasurementError("per-tooth averaging needs the number of flutes");
    Comparison out;
    out.rate_Hz = measured.rate_Hz;
    out.cutoff_Hz = opt.cutoff_Hz;
    out.averaging = opt.averaging;
    out.offset_found = !opt.offset_s;
    out.offset_s = opt.offset_s ? *opt.offset_s : find_offset_s(predicted, measured, &out.alignment_score);

    const double tp0 = std::max(predicted.samples.front().t_s, opt.t_start_s);
    const double tp1 = std::min(predicted.samples.back().t_s, opt.t_end_s);
    Series s;
    std::vector<float> mf[3], pf[3];
    PredictionSampler sampler(predicted.samples);
    const std::vector<float>* src[3] = {&measured.fx_N, &measured.fy_N, &measured.fz_N};
    for (std::size_t i = 0; i < measured.size(); ++i) {
        const double t = measured.t_s(i) + out.offset_s;
        if (t < tp0 || t > tp1) continue;
        const auto v = sampler.at(t);
        s.t_s.push_back(t);
        s.angle_deg.push_back(v.angle_deg);
        s.block.push_back(v.block);
        for (int ax = 0; ax < 3; ++ax) {
            mf[ax].push_back((*src[ax])[i]);
            pf[ax].push_back(static_cast<float>(v.f[ax]));
        }
    }
    if (s.size() < 2)
        throw MeasurementError(fmt::format(
            "{}: empty comparison window: measured [{:g}, {:g}] s shifted by {:g} s does not overlap the prediction "
            "[{:g}, {:g}] s within the window [{:g}, {:g}] s",
            measured.source, measured.t_s(0), measured.t_s(measured.size() - 1), out.offset_s,
            predicted.samples.front().t_s, predicted.samples.back().t_s, opt.t_start_s, opt.t_end_s));
    if (opt.remove_zero) out.zero = zero_line(s.t_s, mf, pf, opt, measured.t_s(0) + out.offset_s);
    if (out.zero.source != ZeroSource::None) {
        out.zero_removed = true;
        for (int ax = 0; ax < 3; ++ax) {
            out.zero_N[ax] = out.zero.zero_N[static_cast<std::size_t>(ax)];
            for (std::size_t i = 0; i < s.size(); ++i)
                mf[ax][i] = static_cast<float>(mf[ax][i] - out.zero.at(s.t_s[i])[static_cast<std::size_t>(ax)]);
        }
    }
    for (int ax = 0; ax < 3; ++ax) {
        if (opt.cutoff_Hz > 0) {
            lowpass_zero_phase(mf[ax], measured.rate_Hz, opt.cutoff_Hz);
            lowpass_zero_phase(pf[ax], measured.rate_Hz, opt.cutoff_Hz);
        }
        s.meas[ax].assign(mf[ax].begin(), mf[ax].end());
        s.pred[ax].assign(pf[ax].begin(), pf[ax].end());
    }
    if (opt.averaging != Averaging::None) {
        const double period_deg = opt.averaging == Averaging::Revolution ? 360.0 : 360.0 / opt.flutes;
        s = period_means(s, period_deg);
        if (s.size() < 2)
            throw MeasurementError(fmt::format("{}: fewer than two whole {} periods in the comparison window",
                                               measured.source, averaging_name(opt.averaging)));
    }
    fill_resultants(s);

    std::vector<std::size_t> all(s.size());
    for (std::size_t i = 0; i < all.size(); ++i) all[i] = i;
    out.overall = scope_metrics(s, all, "overall");
    std::vector<std::int32_t> order;
    std::map<std::int32_t, std::vector<std::size_t>> by_block;
    for (std::size_t i = 0; i < s.size(); ++i) {
        auto& idx = by_block[s.block[i]];
        if (idx.empty()) order.push_back(s.block[i]);
        idx.push_back(i);
    }
    for (std::int32_t b : order) {
        if (b < 0 || by_block[b].size() < 2) continue;
        const std::string name = static_cast<std::size_t>(b) < predicted.block_names.size()
                                     ? predicted.block_names[static_cast<std::size_t>(b)]
                                     : fmt::format("#{}", b);
        out.blocks.push_back(scope_metrics(s, by_block[b], name));
    }
    out.t_s = std::move(s.t_s);
    out.block = std::move(s.block);
    for (int ax = 0; ax < 3; ++ax) {
        out.predicted[ax].assign(s.pred[ax].begin(), s.pred[ax].end());
        out.measured[ax].assign(s.meas[ax].begin(), s.meas[ax].end());
    }
    return out;
}

namespace {

const char* kAxisNames[4] = {"x", "y", "z", "resultant"};

nlohmann::json scope_json(const ScopeMetrics& m) {
    nlohmann::json j = {{"scope", m.scope}, {"t_start_s", m.t_start_s}, {"t_end_s", m.t_end_s}, {"samples", m.samples}};
    for (int ax = 0; ax < 4; ++ax) {
        const AxisMetrics& a = m.axes[ax];
        j[kAxisNames[ax]] = {{"mean_error_N", number_or_null(a.mean_error_N)},
                             {"rmse_N", number_or_null(a.rmse_N)},
                             {"nrmse", number_or_null(a.nrmse)},
                             {"peak_error_N", number_or_null(a.peak_error_N)},
                             {"peak_measured_N", number_or_null(a.peak_measured_N)},
                             {"peak_predicted_N", number_or_null(a.peak_predicted_N)},
                             {"correlation", number_or_null(a.correlation)}};
    }
    return j;
}

template <typename Fill>
void write_file(const std::string& path, Fill fill) {
    const std::string tmp = path + ".tmp";
    {
        std::ofstream out(tmp, std::ios::trunc);
        if (!out) throw std::runtime_error("cannot write " + tmp);
        fill(out);
        if (!out) throw std::runtime_error("writing " + tmp + " failed");
    }
    std::filesystem::rename(tmp, path);
}

}  // namespace

nlohmann::json to_json(const Comparison& c) {
    nlohmann::json blocks = nlohmann::json::array();
    for (const auto& b : c.blocks) blocks.push_back(scope_json(b));
    return {{"offset_s", c.offset_s},
            {"offset_source", c.offset_found ? "cross-correlation" : "given"},
            {"alignment_score", c.offset_found ? number_or_null(c.alignment_score) : nlohmann::json()},
            {"rate_Hz", c.rate_Hz},
            {"cutoff_Hz", c.cutoff_Hz},
            {"averaging", averaging_name(c.averaging)},
            {"zero_removed_N", c.zero_removed ? nlohmann::json{c.zero_N[0], c.zero_N[1], c.zero_N[2]} : nlohmann::json()},
            {"zero", to_json(c.zero)},
            {"overall", scope_json(c.overall)},
            {"blocks", blocks}};
}

void write_comparison_csv(const Comparison& c, const std::string& path) {
    write_file(path, [&](std::ofstream& out) {
        out << "scope,axis,samples,t_start_s,t_end_s,mean_error_N,rmse_N,nrmse,peak_error_N,peak_measured_N,"
               "peak_predicted_N,correlation\n";
        auto rows = [&](const ScopeMetrics& m) {
            for (int ax = 0; ax < 4; ++ax) {
                const AxisMetrics& a = m.axes[ax];
                out << fmt::format("{},{},{},{:.6f},{:.6f},{:.4f},{:.4f},{:.5f},{:.4f},{:.4f},{:.4f},{:.5f}\n",
                                   csv_field(m.scope), kAxisNames[ax], m.samples, m.t_start_s, m.t_end_s,
                                   a.mean_error_N, a.rmse_N, a.nrmse, a.peak_error_N, a.peak_measured_N,
                                   a.peak_predicted_N, a.correlation);
            }
        };
        rows(c.overall);
        for (const auto& b : c.blocks) rows(b);
    });
}

void write_comparison_trace_csv(const Comparison& c, const std::vector<std::string>& block_names,
                                const std::string& path) {
    write_file(path, [&](std::ofstream& out) {
        out << "t_s,block,fx_pred_N,fy_pred_N,fz_pred_N,fx_meas_N,fy_meas_N,fz_meas_N\n";
        for (std::size_t i = 0; i < c.t_s.size(); ++i) {
            const std::int32_t b = c.block[i];
            const std::string name =
                b >= 0 && static_cast<std::size_t>(b) < block_names.size() ? csv_field(block_names[b]) : "";
            out << fmt::format("{:.6f},{},{:.3f},{:.3f},{:.3f},{:.3f},{:.3f},{:.3f}\n", c.t_s[i], name,
                               c.predicted[0][i], c.predicted[1][i], c.predicted[2][i], c.measured[0][i],
                               c.measured[1][i], c.measured[2][i]);
        }
    });
}

}  // namespace cutload::force_model
