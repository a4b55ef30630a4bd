// Cutting-coefficient identification (see calibrate.hpp and docs/compare_calibrate.md).
#include "force_model/calibrate.hpp"

#include <Eigen/Dense>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>

namespace cutload::force_model {

namespace {

constexpr double pi = std::numbers::pi;

double feed_per_tooth_mm(const CutTest& t, int flutes) { return t.feed_mm_min / (flutes * std::abs(t.spindle_rpm)); }

// Immersion window [start, exit], measured clockwise from +Y with the feed along +X (Altintas):
// up milling starts at zero chip thickness, down milling ends at it.
std::array<double, 2> immersion_window(const CutTest& t, double diameter_mm) {
    switch (t.mode) {
        case Immersion::Up: return {0.0, std::acos(1.0 - 2.0 * t.radial_mm / diameter_mm)};
        case Immersion::Down: return {std::acos(2.0 * t.radial_mm / diameter_mm - 1.0), pi};
        case Immersion::Slot: break;
    }
    return {0.0, pi};
}

}  // namespace

Immersion parse_immersion(const std::string& text) {
    if (text == "slot") return Immersion::Slot;
    if (text == "up") return Immersion::Up;
    if (text == "down") return Immersion::Down;
    throw SpecError("mode `" + text + "`: must be slot, up or down");
}

const char* immersion_name(Immersion m) {
    switch (m) {
        case Immersion::Up: return "up";
        case Immersion::Down: return "down";
        case Immersion::Slot: break;
    }
    return "slot";
}

void validate_cut_test(const CutTest& t, const ToolSpec& tool) {
    if (!(t.spindle_rpm > 0 && t.spindle_rpm < 2e5)) throw SpecError("spindle_rpm: must be in (0, 200000)");
    if (!(t.feed_mm_min > 0 && t.feed_mm_min < 2e5)) throw SpecError("feed_mm_min: must be in (0, 200000)");
    if (!(t.axial_mm > 0 && t.axial_mm <= tool.flute_length_mm))
        throw SpecError(fmt::format("axial_mm: must be in (0, {:g}] (the flute length)", tool.flute_length_mm));
    if (t.mode != Immersion::Slot && !(t.radial_mm > 0 && t.radial_mm <= tool.diameter_mm))
        throw SpecError(fmt::format("radial_mm: must be in (0, {:g}] (the tool diameter)", tool.diameter_mm));
}

std::array<double, 6> coefficients_of(const Material& m) {
    return {m.Ktc_N_mm2, m.Krc_N_mm2, m.Kac_N_mm2, m.Kte_N_mm, m.Kre_N_mm, m.Kae_N_mm};
}

Material material_of(const std::array<double, 6>& k, const std::string& name) {
    return {name, k[0], k[1], k[2], k[3], k[4], k[5]};
}

// Altintas' average forces: the tooth-period mean is N a / (2 pi) times the integral of the
// per-length force over the immersion window, with h = c sin(phi). Integrands (per unit coefficient):
//   x: Ktc -c sin cos, Krc -c sin^2, Kte -cos, Kre -sin;  y: Ktc c sin^2, Krc -c sin cos, Kte sin, Kre -cos;
//   z: Kac c sin, Kae 1.
Regressors closed_form_regressors(const ToolSpec& tool, const CutTest& test) {
    if (tool.shape != ToolShape::Flat || tool.taper_deg != 0)
        throw SpecError("closed-form regressors hold for untapered flat end mills only: use the engine model");
    validate_cut_test(test, tool);
    const double c = feed_per_tooth_mm(test, tool.flutes);
    // Not a structured binding: clang before 16 cannot capture one in a lambda (the fuzz build).
    const std::array<double, 2> window = immersion_window(test, tool.diameter_mm);
    const double p0 = window[0], p1 = window[1];
    auto span = [&](auto g) { return g(p1) - g(p0); };
    const double sin_cos = span([](double p) { return -std::cos(2 * p) / 4; });
    const double sin_sq = span([](double p) { return (2 * p - std::sin(2 * p)) / 4; });
    const double cosine = span([](double p) { return std::sin(p); });     // integral of cos
    const double sine = span([](double p) { return -std::cos(p); });      // integral of sin
    const double s = tool.flutes * test.axial_mm / (2 * pi);
    Regressors r{};
    r[0] = {-s * c * sin_cos, -s * c * sin_sq, 0, -s * cosine, -s * sine, 0};
    r[1] = {s * c * sin_sq, -s * c * sin_cos, 0, s * sine, -s * cosine, 0};
    r[2] = {0, 0, s * c * sine, 0, 0, s * (p1 - p0)};
    return r;
}

namespace {

// Mean of rows in [t0, t1] over whole revolutions of spindle angle, trapezoids in angle.
std::array<double, 3> revolution_mean(const std::vector<ForceSample>& rows, double t0, double t1) {
    std::vector<const ForceSample*> w;
    for (const auto& r : rows)
        if (r.t_s >= t0 && r.t_s <= t1) w.push_back(&r);
    std::sort(w.begin(), w.end(), [](auto a, auto b) { return a->t_s < b->t_s; });
    if (w.size() < 2) throw std::logic_error("engine_regressors: no rows in the steady window");
    const double a0 = w.front()->spindle_angle_deg;
    const double a1 = a0 + 360.0 * std::floor((w.back()->spindle_angle_deg - a0) / 360.0);
    if (a1 <= a0) throw std::logic_error("engine_regressors: less than one revolution in the steady window");
    double sum[3] = {0, 0, 0};
    for (std::size_t i = 0; i + 1 < w.size() && w[i]->spindle_angle_deg < a1; ++i) {
        const ForceSample& p = *w[i];
        const ForceSample& q = *w[i + 1];
        const double da = q.spindle_angle_deg - p.spindle_angle_deg;
        if (da <= 0) continue;
        const double u = std::min(1.0, (a1 - p.spindle_angle_deg) / da);
        const double fp[3] = {p.fx_N, p.fy_N, p.fz_N}, fq[3] = {q.fx_N, q.fy_N, q.fz_N};
        for (int ax = 0; ax < 3; ++ax) sum[ax] += 0.5 * u * da * (fp[ax] + fp[ax] + u * (fq[ax] - fp[ax]));
    }
    const double span = a1 - a0;
    return {sum[0] / span, sum[1] / span, sum[2] / span};
}

Material unit_material(int k) {
    std::array<double, 6> c{};
    c[static_cast<std::size_t>(k)] = 1.0;
    return material_of(c, kCoefficientKeys[k]);
}

}  // namespace

// A straight cut along +X through a box whose faces give the immersion window: the tool enters
// from air, passes through the entry transient and cuts `revolutions` steady revolutions.
Regressors engine_regressors(const ToolSpec& tool, const CutTest& test, const EngineRegressorOptions& opt) {
    validate_cut_test(test, tool);
    const double R = tool.diameter_mm / 2, top_z = 5.0, margin = 0.3;
    const auto [p0, p1] = immersion_window(test, tool.diameter_mm);
    const double feed_per_rev = feed_per_tooth_mm(test, tool.flutes) * tool.flutes;
    const double steady_mm = opt.revolutions * feed_per_rev + 2 * margin + feed_per_rev;

    RunSpec spec;
    spec.tool = tool;
    spec.resolution = opt.resolution;
    spec.stock.min_mm[0] = 0;
    spec.stock.max_mm[0] = steady_mm + R + 1;
    spec.stock.min_mm[1] = p1 >= pi - 1e-12 ? -R - 1 : R * std::cos(p1);
    spec.stock.max_mm[1] = p0 <= 1e-12 ? R + 1 : R * std::cos(p0);
    spec.stock.min_mm[2] = 0;
    spec.stock.max_mm[2] = top_z;
    spec.limits = {};

    const double start_x = -R - 0.5, speed = test.feed_mm_min / 60.0, step_s = 1e-3;
    motion_io::MotionModel m;
    m.step_s = step_s;
    m.block_names = {"calibration"};
    m.session_start = {0};
    const auto n = static_cast<std::size_t>(std::ceil((steady_mm - start_x) / speed / step_s)) + 1;
    for (std::size_t i = 0; i < n; ++i) {
        const double t = static_cast<double>(i) * step_s;
        m.t_s.push_back(t);
        m.x_mm.push_back(start_x + speed * t);
        m.y_mm.push_back(0);
        m.z_mm.push_back(top_z - test.axial_mm);
        m.vx_mm_s.push_back(speed);
        m.vy_mm_s.push_back(0);
        m.vz_mm_s.push_back(0);
        m.spindle_rpm.push_back(test.spindle_rpm);
        m.spindle_angle_deg.push_back(6.0 * test.spindle_rpm * t);
        m.block.push_back(0);
    }
    const double t0 = (margin - start_x) / speed, t1 = (steady_mm - margin - start_x) / speed;

    Regressors r{};
    PredictOptions popt;
    popt.device = opt.device;
    for (int k = 0; k < 6; ++k) {
        spec.material = unit_material(k);
        const Prediction p = predict(m, spec, popt);
        const auto mean = revolution_mean(p.samples, t0, t1);
        for (int ax = 0; ax < 3; ++ax) r[static_cast<std::size_t>(ax)][static_cast<std::size_t>(k)] = mean[ax];
    }
    return r;
}

double tooth_air_fraction(const ToolSpec& tool, const CutTest& test) {
    if (tool.shape != ToolShape::Flat || tool.taper_deg != 0 || test.mode == Immersion::Slot || tool.flutes < 1)
        return 0.0;
    const auto [p0, p1] = immersion_window(test, tool.diameter_mm);
    const double lag = test.axial_mm * std::tan(tool.helix_deg * pi / 180.0) / (tool.diameter_mm / 2);
    return std::max(0.0, 1.0 - (p1 - p0 + std::abs(lag)) / (2 * pi / tool.flutes));
}

std::array<double, 3> to_feed_frame(const std::array<double, 3>& f, double feed_direction_deg) {
    const double a = feed_direction_deg * pi / 180.0, c = std::cos(a), s = std::sin(a);
    return {c * f[0] + s * f[1], -s * f[0] + c * f[1], f[2]};
}

namespace {

CalibrationFit solve(const Eigen::MatrixXd& A, const Eigen::VectorXd& b, const std::vector<std::size_t>& group_end,
                     const std::string& name) {
    if (A.rows() < 6)
        throw SpecError(fmt::format("{} equations cannot determine six coefficients: add tests", A.rows()));
    Eigen::VectorXd scale = A.colwise().norm().transpose();
    for (Eigen::Index k = 0; k < 6; ++k)
        if (scale[k] == 0)
            throw SpecError(fmt::format("the tests carry no information on {} (its regressor is zero)",
                                        kCoefficientKeys[k]));
    const Eigen::MatrixXd As = A * scale.cwiseInverse().asDiagonal();
    Eigen::JacobiSVD<Eigen::MatrixXd> svd(As, Eigen::ComputeThinU | Eigen::ComputeThinV);
    const auto& sv = svd.singularValues();
    CalibrationFit fit;
    fit.condition_number = sv[0] / sv[sv.size() - 1];
    if (!(fit.condition_number < 1e10))
        throw SpecError(fmt::format("the tests cannot separate the six coefficients (condition number {:.3g}): use "
                                    "several feeds, and for the edge terms partial immersions",
                                    fit.condition_number));
    const Eigen::VectorXd k = svd.solve(b).cwiseQuotient(scale);
    const Eigen::VectorXd res = A * k - b;
    fit.equations = static_cast<std::size_t>(A.rows());
    fit.rms_residual_N = std::sqrt(res.squaredNorm() / static_cast<double>(A.rows()));
    const double rms_b = std::sqrt(b.squaredNorm() / static_cast<double>(A.rows()));
    fit.relative_rms_residual = rms_b > 0 ? fit.rms_residual_N / rms_b : 0.0;
    std::size_t begin = 0;
    for (std::size_t end : group_end) {
        const auto n = static_cast<Eigen::Index>(end - begin);
        fit.group_rms_residual_N.push_back(
            n > 0 ? std::sqrt(res.segment(static_cast<Eigen::Index>(begin), n).squaredNorm() / static_cast<double>(n))
                  : 0.0);
        begin = end;
    }
    fit.material = material_of({k[0], k[1], k[2], k[3], k[4], k[5]}, name);
    return fit;
}

}  // namespace

CalibrationFit fit_mean_forces(const std::vector<Regressors>& regressors,
                               const std::vector<std::array<double, 3>>& mean_force_feed_N, const std::string& name) {
    if (regressors.size() != mean_force_feed_N.size())
        throw std::invalid_argument("fit_mean_forces: one mean force per regressor set");
    const auto rows = static_cast<Eigen::Index>(3 * regressors.size());
    Eigen::MatrixXd A(rows, 6);
    Eigen::VectorXd b(rows);
    std::vector<std::size_t> group_end;
    for (std::size_t t = 0; t < regressors.size(); ++t) {
        for (std::size_t ax = 0; ax < 3; ++ax) {
            const auto row = static_cast<Eigen::Index>(3 * t + ax);
            for (std::size_t k = 0; k < 6; ++k) A(row, static_cast<Eigen::Index>(k)) = regressors[t][ax][k];
            b[row] = mean_force_feed_N[t][ax];
        }
        group_end.push_back(3 * t + 3);
    }
    return solve(A, b, group_end, name);
}

CalibrationFit calibrate_from_runs(const std::vector<MeasuredRun>& runs, const RunCalibrationOptions& opt,
                                   const std::string& name) {
    std::vector<double> a_rows, b_rows;   // row-major, six regressors per equation
    std::vector<std::size_t> group_end;
    for (const MeasuredRun& run : runs) {
        if (!run.motion || !run.measured) throw std::invalid_argument("calibrate_from_runs: missing motion or measurement");
        PredictOptions popt;
        popt.device = opt.device;
        std::array<PredictedTrace, 6> unit;
        RunSpec spec = run.spec;
        for (int k = 0; k < 6; ++k) {
            spec.material = unit_material(k);
            unit[static_cast<std::size_t>(k)] = predicted_trace(predict(*run.motion, spec, popt));
        }
        // Align once, on the prediction with the run's own coefficients (Ktc alone when it has none).
        CompareOptions copt;
        copt.cutoff_Hz = opt.cutoff_Hz;
        copt.averaging = Averaging::Revolution;
        copt.offset_s = run.offset_s;
        if (!copt.offset_s) {
            for (const auto& u : unit)
                if (u.samples.size() != unit[0].samples.size())
                    throw std::logic_error("calibrate_from_runs: unit predictions differ in their rows");
            PredictedTrace guess = unit[0];
            auto k = coefficients_of(run.spec.material);
            if (k[0] <= 0) k = {1, 0, 0, 0, 0, 0};
            for (std::size_t i = 0; i < guess.samples.size(); ++i) {
                float f[3] = {0, 0, 0};
                for (std::size_t c = 0; c < 6; ++c) {
                    const ForceSample& s = unit[c].samples[i];
                    f[0] += static_cast<float>(k[c]) * s.fx_N;
                    f[1] += static_cast<float>(k[c]) * s.fy_N;
                    f[2] += static_cast<float>(k[c]) * s.fz_N;
                }
                guess.samples[i].fx_N = f[0];
                guess.samples[i].fy_N = f[1];
                guess.samples[i].fz_N = f[2];
            }
            copt.offset_s = find_offset_s(guess, *run.measured);
        }
        std::array<Comparison, 6> per;
        for (std::size_t c = 0; c < 6; ++c) per[c] = compare(unit[c], *run.measured, copt);
        // Revolutions where no coefficient gives any force are air: their measured mean is the zero offset.
        const std::size_t n = per[0].t_s.size();
        std::vector<bool> air(n, true);
        double peak = 0;
        for (std::size_t i = 0; i < n; ++i)
            for (std::size_t c = 0; c < 6; ++c)
                for (int ax = 0; ax < 3; ++ax) peak = std::max(peak, std::abs(double(per[c].predicted[ax][i])));
        for (std::size_t i = 0; i < n; ++i)
            for (std::size_t c = 0; c < 6; ++c)
                for (int ax = 0; ax < 3; ++ax)
                    if (std::abs(per[c].predicted[ax][i]) > 1e-6 * peak) air[i] = false;
        double zero[3] = {0, 0, 0};
        std::size_t n_air = 0;
        for (std::size_t i = 0; i < n; ++i)
            if (air[i]) {
                for (int ax = 0; ax < 3; ++ax) zero[ax] += per[0].measured[ax][i];
                ++n_air;
            }
        for (int ax = 0; ax < 3; ++ax) zero[ax] = n_air ? zero[ax] / static_cast<double>(n_air) : 0.0;
        for (std::size_t i = 0; i < n; ++i) {
            if (air[i]) continue;
            for (int ax = 0; ax < 3; ++ax) {
                for (std::size_t c = 0; c < 6; ++c) a_rows.push_back(per[c].predicted[ax][i]);
                b_rows.push_back(per[0].measured[ax][i] - zero[ax]);
            }
        }
        group_end.push_back(b_rows.size());
    }
    const auto rows = static_cast<Eigen::Index>(b_rows.size());
    const Eigen::MatrixXd A = Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, 6, Eigen::RowMajor>>(a_rows.data(), rows, 6);
    const Eigen::VectorXd b = Eigen::Map<const Eigen::VectorXd>(b_rows.data(), rows);
    return solve(A, b, group_end, name);
}

nlohmann::json material_json(const Material& m) {
    nlohmann::json j = {{"name", m.name}};
    const auto k = coefficients_of(m);
    for (std::size_t i = 0; i < 6; ++i) j[kCoefficientKeys[i]] = k[i];
    return j;
}

}  // namespace cutload::force_model
