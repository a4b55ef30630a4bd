#include "force_model/reference.hpp"

#define CL_TARGET_OPENCL_VERSION 120
#include <CL/cl.h>
#include <catch2/catch.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <numbers>

namespace cutload::testref {

namespace {

constexpr double pi = std::numbers::pi;

double deg_to_rad(double deg) { return deg * pi / 180.0; }

// Per unit axial length at immersion phi (see the header for the convention).
Forces element_forces(const Coefficients& k, double chip_mm, double phi_rad, double radius_mm) {
    const double ft = k.Ktc_N_mm2 * chip_mm + k.Kte_N_mm;
    const double fr = k.Krc_N_mm2 * chip_mm + k.Kre_N_mm;
    const double fa = k.Kac_N_mm2 * chip_mm + k.Kae_N_mm;
    const double s = std::sin(phi_rad), c = std::cos(phi_rad);
    return {-ft * c - fr * s, ft * s - fr * c, fa, radius_mm * ft / 1000.0};
}

}  // namespace

Coefficients cutting_part(const Coefficients& k) {
    Coefficients c = k;
    c.Kte_N_mm = c.Kre_N_mm = c.Kae_N_mm = 0;
    return c;
}

Coefficients edge_part(const Coefficients& k) {
    Coefficients c = k;
    c.Ktc_N_mm2 = c.Krc_N_mm2 = c.Kac_N_mm2 = 0;
    return c;
}

double up_milling_exit_rad(double radial_depth_mm, double diameter_mm) {
    // The last cutting point lies on the line y = R - ae: R cos(phi) = R - ae.
    return std::acos(1.0 - 2.0 * radial_depth_mm / diameter_mm);
}

double down_milling_start_rad(double radial_depth_mm, double diameter_mm) {
    // The first cutting point lies on the line y = -R + ae: R cos(phi) = ae - R.
    return std::acos(2.0 * radial_depth_mm / diameter_mm - 1.0);
}

Cut slot_cut(double diameter_mm, int flutes, double helix_deg, double axial_mm, double feed_per_tooth_mm) {
    return {diameter_mm, flutes, helix_deg, axial_mm, feed_per_tooth_mm, 0.0, pi};
}

Cut up_cut(double diameter_mm, int flutes, double helix_deg, double axial_mm, double feed_per_tooth_mm,
           double radial_mm) {
    return {diameter_mm, flutes, helix_deg, axial_mm, feed_per_tooth_mm, 0.0,
            up_milling_exit_rad(radial_mm, diameter_mm)};
}

Cut down_cut(double diameter_mm, int flutes, double helix_deg, double axial_mm, double feed_per_tooth_mm,
             double radial_mm) {
    return {diameter_mm, flutes, helix_deg, axial_mm, feed_per_tooth_mm,
            down_milling_start_rad(radial_mm, diameter_mm), pi};
}

// Average over one tooth period (Altintas, Manufacturing Automation, 2nd ed., ch. 2, average
// milling forces). With N flutes, axial depth a and feed per tooth c, every flute passes the
// window once per revolution, so the mean is (N a / 2 pi) times the integral of the per-length
// force over [phi_st, phi_ex]; a helix only shifts each axial slice in phase, which a full-period
// average does not see. With h = c sin(phi) and the antiderivatives
//   S(phi) = int sin^2 = (2 phi - sin 2phi) / 4,   P(phi) = int sin cos = -cos(2 phi) / 4:
//   int fx = -Ktc c P - Krc c S - Kte sin(phi) + Kre cos(phi)
//          = (c / 4) [Ktc cos 2phi - Krc (2 phi - sin 2phi)] - Kte sin(phi) + Kre cos(phi)
//   int fy =  Ktc c S - Krc c P - Kte cos(phi) - Kre sin(phi)
//          = (c / 4) [Ktc (2 phi - sin 2phi) + Krc cos 2phi] - Kte cos(phi) - Kre sin(phi)
//   int fz = -Kac c cos(phi) + Kae phi
//   int T  = R (-Ktc c cos(phi) + Kte phi)
// each evaluated between phi_st and phi_ex. These are Altintas' published average-force
// expressions (the (N a c / 8 pi) and (N a / 2 pi) groups). Slot (0..pi), as a hand check:
//   Fx = -N a c Krc / 4 - N a Kre / pi,   Fy = N a c Ktc / 4 + N a Kte / pi,
//   Fz = N a c Kac / pi + N a Kae / 2,    T = N a R (c Ktc / pi + Kte / 2).
Forces average_forces(const Cut& cut, const Coefficients& k) {
    const double c = cut.feed_per_tooth_mm;
    const double radius_mm = cut.diameter_mm / 2.0;
    auto integral = [&](double phi) {
        Forces f;
        f.fx_N = c / 4.0 * (k.Ktc_N_mm2 * std::cos(2 * phi) - k.Krc_N_mm2 * (2 * phi - std::sin(2 * phi))) -
                 k.Kte_N_mm * std::sin(phi) + k.Kre_N_mm * std::cos(phi);
        f.fy_N = c / 4.0 * (k.Ktc_N_mm2 * (2 * phi - std::sin(2 * phi)) + k.Krc_N_mm2 * std::cos(2 * phi)) -
                 k.Kte_N_mm * std::cos(phi) - k.Kre_N_mm * std::sin(phi);
        f.fz_N = -k.Kac_N_mm2 * c * std::cos(phi) + k.Kae_N_mm * phi;
        f.torque_Nm = radius_mm * (-k.Ktc_N_mm2 * c * std::cos(phi) + k.Kte_N_mm * phi) / 1000.0;
        return f;
    };
    const Forces hi = integral(cut.phi_exit_rad), lo = integral(cut.phi_start_rad);
    const double scale = cut.flutes * cut.axial_depth_mm / (2 * pi);
    return {scale * (hi.fx_N - lo.fx_N), scale * (hi.fy_N - lo.fy_N), scale * (hi.fz_N - lo.fz_N),
            scale * (hi.torque_Nm - lo.torque_Nm)};
}

Forces instantaneous_forces(const Cut& cut, const Coefficients& k, double phi_tool_rad, int axial_slices) {
    return instantaneous_forces_where(cut, k, phi_tool_rad, axial_slices, [&cut](double phi_rad, double) {
        return phi_rad >= cut.phi_start_rad && phi_rad <= cut.phi_exit_rad;
    });
}

Forces instantaneous_forces_where(const Cut& cut, const Coefficients& k, double phi_tool_rad, int axial_slices,
                                  const std::function<bool(double phi_rad, double z_mm)>& cuts) {
    const double radius_mm = cut.diameter_mm / 2.0;
    const double dz_mm = cut.axial_depth_mm / axial_slices;
    const double lag_per_mm = std::tan(deg_to_rad(cut.helix_deg)) / radius_mm;
    const double pitch_rad = 2 * pi / cut.flutes;
    Forces sum;
    for (int flute = 0; flute < cut.flutes; ++flute)
        for (int slice = 0; slice < axial_slices; ++slice) {
            const double z_mm = (slice + 0.5) * dz_mm;
            // A right-hand helix turning M03: higher slices reach a given immersion later.
            const double phi = std::remainder(phi_tool_rad + flute * pitch_rad - lag_per_mm * z_mm - pi, 2 * pi) + pi;
            if (!cuts(phi, z_mm)) continue;
            const Forces f = element_forces(k, cut.feed_per_tooth_mm * std::sin(phi), phi, radius_mm);
            sum.fx_N += f.fx_N * dz_mm;
            sum.fy_N += f.fy_N * dz_mm;
            sum.fz_N += f.fz_N * dz_mm;
            sum.torque_Nm += f.torque_Nm * dz_mm;
        }
    return sum;
}

void add_flank_slice(Forces& sum, const Coefficients& k, double r, double d, double sb, double cb, bool up,
                     double feed_per_tooth_mm, double dz, int phi_steps) {
    const double phi0 = up ? 0.0 : std::acos(-d / r), phi1 = up ? std::acos(d / r) : std::numbers::pi;
    const double dphi = (phi1 - phi0) / phi_steps;
    for (int ip = 0; ip < phi_steps; ++ip) {
        const double phi = phi0 + (ip + 0.5) * dphi, s = std::sin(phi), co = std::cos(phi);
        const double h = feed_per_tooth_mm * s * cb;
        const double ft = (k.Ktc_N_mm2 * h + k.Kte_N_mm) / cb, fr = (k.Krc_N_mm2 * h + k.Kre_N_mm) / cb,
                     fa = (k.Kac_N_mm2 * h + k.Kae_N_mm) / cb;
        const double radial_out = -fr * cb + fa * sb;
        const double w = dz * dphi;
        sum.fx_N += w * (-ft * co + radial_out * s);
        sum.fy_N += w * (ft * s + radial_out * co);
        sum.fz_N += w * (fr * sb + fa * cb);
        sum.torque_Nm += w * r * ft / 1000;
    }
}

double resultant_N(const Forces& f) { return std::sqrt(f.fx_N * f.fx_N + f.fy_N * f.fy_N + f.fz_N * f.fz_N); }

double relative_force_error(const Forces& a, const Forces& b) {
    const Forces d{a.fx_N - b.fx_N, a.fy_N - b.fy_N, a.fz_N - b.fz_N, 0};
    return resultant_N(d) / resultant_N(b);
}

force_model::RunSpec flat_tool_spec(const Cut& cut, const Coefficients& k, const force_model::StockBox& box,
                                    double grid_mm) {
    force_model::RunSpec spec;
    spec.tool.shape = force_model::ToolShape::Flat;
    spec.tool.diameter_mm = cut.diameter_mm;
    spec.tool.flutes = cut.flutes;
    spec.tool.helix_deg = cut.helix_deg;
    spec.tool.corner_radius_mm = 0;
    spec.tool.flute_length_mm = 20;
    spec.tool.stickout_mm = 30;
    spec.tool.holder = {cut.diameter_mm * 4, 40};
    spec.material = {"reference", k.Ktc_N_mm2, k.Krc_N_mm2, k.Kac_N_mm2, k.Kte_N_mm, k.Kre_N_mm, k.Kae_N_mm};
    spec.stock = box;
    spec.resolution = {2.0, 0.1, grid_mm};
    return spec;
}

namespace {

std::array<double, 2> rotate_xy(double x, double y, int quarter_turns) {
    for (int i = 0; i < ((quarter_turns % 4) + 4) % 4; ++i) {
        const double nx = -y;
        y = x;
        x = nx;
    }
    return {x, y};
}

}  // namespace

Forces rotate_quarter_turns(const Forces& f, int quarter_turns) {
    const auto xy = rotate_xy(f.fx_N, f.fy_N, quarter_turns);
    return {xy[0], xy[1], f.fz_N, f.torque_Nm};
}

StraightSetup straight_setup(const Cut& cut, double spindle_rpm, int quarter_turns, double steady_mm) {
    const double radius_mm = cut.diameter_mm / 2.0, top_z_mm = 5.0, margin_mm = 0.3;
    const double tip_z_mm = top_z_mm - cut.axial_depth_mm;
    // Material sits where the immersion window points (a cutting point is at R (sin, cos) of phi):
    // from the window's edges to beyond the tool on the open sides.
    const double y_lo = cut.phi_exit_rad >= pi - 1e-12 ? -radius_mm - 1.0 : radius_mm * std::cos(cut.phi_exit_rad);
    const double y_hi = cut.phi_start_rad <= 1e-12 ? radius_mm + 1.0 : radius_mm * std::cos(cut.phi_start_rad);
    const double x_lo = 0.0, x_hi = steady_mm + radius_mm + 1.0;

    StraightSetup s;
    const auto c0 = rotate_xy(x_lo, y_lo, quarter_turns), c1 = rotate_xy(x_hi, y_hi, quarter_turns);
    s.box.min_mm[0] = std::min(c0[0], c1[0]);
    s.box.max_mm[0] = std::max(c0[0], c1[0]);
    s.box.min_mm[1] = std::min(c0[1], c1[1]);
    s.box.max_mm[1] = std::max(c0[1], c1[1]);
    s.box.min_mm[2] = 0;
    s.box.max_mm[2] = top_z_mm;

    const double start_x = -radius_mm - 0.5;
    const auto p0 = rotate_xy(start_x, 0, quarter_turns), p1 = rotate_xy(steady_mm, 0, quarter_turns);
    s.path.start_mm = {p0[0], p0[1], tip_z_mm};
    s.path.segments = {line_to({p1[0], p1[1], tip_z_mm}, "N10")};
    s.path.spindle_rpm = spindle_rpm;
    s.path.feed_mm_min = cut.feed_per_tooth_mm * cut.flutes * spindle_rpm;
    const double speed_mm_s = s.path.feed_mm_min / 60.0;
    s.steady_t0_s = (margin_mm - start_x) / speed_mm_s;
    s.steady_t1_s = (steady_mm - margin_mm - start_x) / speed_mm_s;
    return s;
}

namespace {

bool opencl_platform_exists() {
    cl_uint count = 0;
    return clGetPlatformIDs(0, nullptr, &count) == CL_SUCCESS && count > 0;
}

}  // namespace

std::vector<force_model::Device> devices_under_test() {
    static const bool opencl = opencl_platform_exists();
    if (!opencl) {
        WARN("no OpenCL platform: the OpenCL path is not tested here");
        return {force_model::Device::Cpu};
    }
    return {force_model::Device::Cpu, force_model::Device::OpenCL};
}

const char* device_name(force_model::Device d) { return d == force_model::Device::Cpu ? "cpu" : "opencl"; }

void report_figure(const std::string& line) {
    static const bool verbose = std::getenv("CUTLOAD_PHYS_VERBOSE") != nullptr;
    if (verbose) std::printf("PHYS %s\n", line.c_str());
}

namespace {

std::vector<force_model::ForceSample> window(const std::vector<force_model::ForceSample>& samples, double t0_s,
                                             double t1_s) {
    std::vector<force_model::ForceSample> w;
    for (const auto& s : samples)
        if (s.t_s >= t0_s && s.t_s <= t1_s) w.push_back(s);
    std::sort(w.begin(), w.end(), [](const auto& a, const auto& b) { return a.t_s < b.t_s; });
    return w;
}

}  // namespace

SteadyMean steady_mean(const std::vector<force_model::ForceSample>& samples, double t0_s, double t1_s, int flutes) {
    const auto w = window(samples, t0_s, t1_s);
    SteadyMean m;
    m.samples = w.size();
    if (w.size() < 2) return m;
    const double period_deg = 360.0 / flutes;
    const double a0 = w.front().spindle_angle_deg;
    m.tooth_periods = static_cast<int>(std::floor((w.back().spindle_angle_deg - a0) / period_deg));
    if (m.tooth_periods < 1) return m;
    const double a1 = a0 + m.tooth_periods * period_deg;
    double fx = 0, fy = 0, fz = 0, tq = 0, pw = 0;
    for (std::size_t i = 0; i + 1 < w.size() && w[i].spindle_angle_deg < a1; ++i) {
        const auto& p = w[i];
        const auto& q = w[i + 1];
        const double da = q.spindle_angle_deg - p.spindle_angle_deg;
        m.max_angle_gap_deg = std::max(m.max_angle_gap_deg, da);
        if (da <= 0) continue;
        // Clip the last trapezoid at a1, interpolating its right end.
        const double u = std::min(1.0, (a1 - p.spindle_angle_deg) / da);
        auto lerp = [u](double a, double b) { return a + u * (b - a); };
        const double w_deg = u * da;
        fx += 0.5 * w_deg * (p.fx_N + lerp(p.fx_N, q.fx_N));
        fy += 0.5 * w_deg * (p.fy_N + lerp(p.fy_N, q.fy_N));
        fz += 0.5 * w_deg * (p.fz_N + lerp(p.fz_N, q.fz_N));
        tq += 0.5 * w_deg * (p.torque_Nm + lerp(p.torque_Nm, q.torque_Nm));
        pw += 0.5 * w_deg * (p.power_kW + lerp(p.power_kW, q.power_kW));
    }
    const double span = a1 - a0;
    m.forces = {fx / span, fy / span, fz / span, tq / span};
    m.power_kW = pw / span;
    return m;
}

TraceFit fit_trace(const std::vector<force_model::ForceSample>& samples, double t0_s, double t1_s, const Cut& cut,
                   const Coefficients& k) {
    const auto w = window(samples, t0_s, t1_s);
    TraceFit fit;
    fit.samples = w.size();
    if (w.empty()) return fit;
    // The reference over one tooth period, tabulated finely enough that interpolating it is exact
    // to well under the tolerance.
    const double period_deg = 360.0 / cut.flutes, table_step_deg = 0.02;
    const auto n = static_cast<std::size_t>(std::lround(period_deg / table_step_deg));
    std::vector<Forces> table(n + 1);
    for (std::size_t j = 0; j <= n; ++j) {
        table[j] = instantaneous_forces(cut, k, static_cast<double>(j) * table_step_deg * pi / 180.0);
        fit.peak_reference_N = std::max(fit.peak_reference_N, resultant_N(table[j]));
    }
    double peak_torque = 0;
    for (const auto& f : table) peak_torque = std::max(peak_torque, std::abs(f.torque_Nm));
    auto reference_at = [&](double angle_deg) {
        const double a = angle_deg - period_deg * std::floor(angle_deg / period_deg);
        const double x = a / table_step_deg;
        const auto j = std::min(static_cast<std::size_t>(x), n - 1);
        const double u = x - static_cast<double>(j);
        const Forces& p = table[j];
        const Forces& q = table[j + 1];
        return Forces{p.fx_N + u * (q.fx_N - p.fx_N), p.fy_N + u * (q.fy_N - p.fy_N), p.fz_N + u * (q.fz_N - p.fz_N),
                      p.torque_Nm + u * (q.torque_Nm - p.torque_Nm)};
    };
    auto mean_square = [&](double offset_deg, double* torque_ms) {
        double sum = 0, sum_t = 0;
        for (const auto& s : w) {
            const Forces r = reference_at(s.spindle_angle_deg + offset_deg);
            const double dx = s.fx_N - r.fx_N, dy = s.fy_N - r.fy_N, dz = s.fz_N - r.fz_N;
            sum += dx * dx + dy * dy + dz * dz;
            const double dt = s.torque_Nm - r.torque_Nm;
            sum_t += dt * dt;
        }
        if (torque_ms) *torque_ms = sum_t / static_cast<double>(w.size());
        return sum / static_cast<double>(w.size());
    };
    double best = std::numeric_limits<double>::infinity(), best_offset = 0;
    for (double off = 0; off < period_deg; off += 0.1) {
        const double e = mean_square(off, nullptr);
        if (e < best) best = e, best_offset = off;
    }
    const double coarse = best_offset;
    for (double off = coarse - 0.1; off <= coarse + 0.1; off += 0.005) {
        const double e = mean_square(off, nullptr);
        if (e < best) best = e, best_offset = off;
    }
    double torque_ms = 0;
    mean_square(best_offset, &torque_ms);
    fit.offset_deg = best_offset;
    fit.rms_rel = std::sqrt(best) / fit.peak_reference_N;
    fit.torque_rms_rel = peak_torque > 0 ? std::sqrt(torque_ms) / peak_torque : 0;
    return fit;
}

}  // namespace cutload::testref
