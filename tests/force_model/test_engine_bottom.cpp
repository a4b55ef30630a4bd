// Flat-bottom chip limited by the material there: a bottom edge point removes at most the material on
// its ray between itself and the previous tooth's pass. An interpolation dip of a retract below a
// floor cut earlier must not engage the whole bottom with its full edge force (demo N510: 214 N of
// Fz), while a real plunge keeps the model's full bottom-edge load.
#include "force_model/engine.hpp"
#include "force_model/engine_fixtures.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

using namespace cutload;
using namespace cutload::enginetest;
using force_model::Device;

namespace {

constexpr double kFloorZ_mm = 7;     // slot floor, 3 mm below the top of the 10 mm box
constexpr double kRestX_mm = 20;     // where the tool rests on the floor and retracts

std::vector<Device> devices_to_test(const char* what) {
    std::vector<Device> devices{Device::Cpu};
    if (opencl_available()) devices.push_back(Device::OpenCL);
    else WARN("no OpenCL device: " << what << " runs on the CPU path only");
    return devices;
}

const char* name(Device d) { return d == Device::Cpu ? "cpu" : "opencl"; }

// Appends one 1 ms sample at rest-spindle speed, the angle integrated like legs_motion does.
void append(motion_io::MotionModel& m, double x, double y, double z, double vz_mm_s) {
    const double rpm = m.spindle_rpm.back();
    m.t_s.push_back(m.t_s.back() + m.step_s);
    m.x_mm.push_back(x);
    m.y_mm.push_back(y);
    m.z_mm.push_back(z);
    m.vx_mm_s.push_back(0);
    m.vy_mm_s.push_back(0);
    m.vz_mm_s.push_back(vz_mm_s);
    m.spindle_rpm.push_back(rpm);
    m.spindle_angle_deg.push_back(m.spindle_angle_deg.back() + 6.0 * rpm * m.step_s);
    m.block.push_back(m.block.back());
}

struct Dip {
    double t_from_s = 0, t_to_s = 0;   // the two sample intervals of the dip
    motion_io::MotionModel motion;
};

// A slot through the box at the floor height, back along it to x = 20 (a re-cut of the finished
// slot: no load), a rest on the floor, then a dip of `dip_mm` below the floor within one 1 ms sample
// interval (zero tangents at both ends, as a Hermite overshoot at a retract looks), back to the floor
// and up at 600 mm/min. A 1 ms dip is a third of a tooth period (2 flutes, 10000 rpm): the feed per
// tooth it implies (1.5 dip / 1 ms x 3 ms, peak) is 4.5 times the dip depth.
Dip dip_motion(double dip_mm) {
    const double y = 10;
    Dip d;
    d.motion = legs_motion({-10, y, kFloorZ_mm}, {{{50, y, kFloorZ_mm}, 6000, "N10"},
                                                  {{kRestX_mm, y, kFloorZ_mm}, 6000, "N20"},
                                                  {{kRestX_mm, y, kFloorZ_mm}, 6000, "N30"}});
    auto& m = d.motion;
    for (int k = 0; k < 10; ++k) append(m, kRestX_mm, y, kFloorZ_mm, 0);
    d.t_from_s = m.t_s.back();
    append(m, kRestX_mm, y, kFloorZ_mm - dip_mm, 0);
    append(m, kRestX_mm, y, kFloorZ_mm, 0);
    d.t_to_s = m.t_s.back();
    for (int k = 1; k <= 100; ++k) append(m, kRestX_mm, y, kFloorZ_mm + 0.01 * k, 10);
    return d;
}

struct DipPeak {
    double fz_N = 0, chip_mm = 0;
};

DipPeak dip_peak(const Dip& d, Device device) {
    force_model::PredictOptions o;
    o.device = device;
    const auto p = force_model::predict(d.motion, base_spec(), o);
    DipPeak peak;
    int rows = 0;
    for (const auto& s : p.samples) {
        if (s.t_s < d.t_from_s || s.t_s > d.t_to_s) continue;
        ++rows;
        peak.fz_N = std::max(peak.fz_N, std::abs(double(s.fz_N)));
        peak.chip_mm = std::max(peak.chip_mm, double(s.chip_mm));
    }
    REQUIRE(rows >= 55);   // 2 ms at 10000 rpm is 120 deg: 60 rows of 2 deg
    return peak;
}

}  // namespace

TEST_CASE("a retract that dips below a swept floor by less than the minimum chip carries no bottom load") {
    // A 0.4 um dip (demo N510: about 0.4 um at 0.5 to 0.8 um per tooth). Its feed per tooth peaks at
    // 1.8 um, above the 0.5 um minimum chip, so an unlimited bottom engages all 8 mm of bottom edge
    // with Kre db each: 26.6 N/mm x 8 mm = 213 N of Fz. With the chip limited to the material under
    // the floor (at most 0.4 um) no bottom element cuts. The bound is one bottom element's edge force,
    // Kre x 0.1 mm = 2.66 N: not a single element may engage (the periphery re-cuts the finished slot
    // with no load).
    const Dip d = dip_motion(0.0004);
    const double one_element_N = base_spec().material.Kre_N_mm * base_spec().resolution.axial_step_mm;
    for (Device device : devices_to_test("the shallow dip test")) {
        const DipPeak peak = dip_peak(d, device);
        INFO(name(device) << ": peak |Fz| " << peak.fz_N << " N, chip " << peak.chip_mm << " mm");
        CHECK(peak.fz_N < one_element_N);
    }
}

TEST_CASE("a bottom edge point cuts no thicker chip than the material between it and the floor") {
    // A 3 um dip is a real cut of the floor, but its bottom chip is the material under the floor,
    // at most 3 um, not the 13.5 um feed per tooth of the fast dip.
    const Dip d = dip_motion(0.003);
    for (Device device : devices_to_test("the deep dip test")) {
        const DipPeak peak = dip_peak(d, device);
        INFO(name(device) << ": peak |Fz| " << peak.fz_N << " N, chip " << peak.chip_mm << " mm");
        CHECK(peak.chip_mm <= 0.003 + 1e-5);
        CHECK(peak.chip_mm > 0.0025);
        // All 8 mm of bottom edge engaged: Kre x 8 mm plus the chip term.
        CHECK(peak.fz_N > 0.95 * base_spec().material.Kre_N_mm * base_spec().tool.diameter_mm);
    }
}

TEST_CASE("a straight plunge loads the flat bottom with the model's full edge and chip force") {
    // Plunge at x = 20, y = 10 from 1 mm above the box to 3 mm into it at 0.05 mm per tooth
    // (1000 mm/min, 2 flutes, 10000 rpm). Only the bottom cuts (the periphery's normal is
    // horizontal, h = 0). Each bottom element has n = -z, so by the element force model
    // dFz = -dFr nz = (Krc h + Kre) db, and the torque r dFt = r (Ktc h + Kte) db. Summed over the
    // bottom edge of both flutes (r from 0 to R):
    //   Fz = N (Krc h + Kre) R, T = N (Ktc h + Kte) R^2 / 2.
    // The lagged stock (0.4 mm of travel) leaves more than h of material under every bottom point
    // once the tip is 0.5 mm in, so the material limit must not reduce the chip there.
    const auto spec = base_spec();
    const auto& k = spec.material;
    const double h_mm = 0.05, radius_mm = spec.tool.diameter_mm / 2;
    const double fz_expected_N = spec.tool.flutes * (k.Krc_N_mm2 * h_mm + k.Kre_N_mm) * radius_mm;
    const double torque_expected_Nm =
        spec.tool.flutes * (k.Ktc_N_mm2 * h_mm + k.Kte_N_mm) * radius_mm * radius_mm / 2 / 1000;
    const auto m = legs_motion({kRestX_mm, 10, 11}, {{{kRestX_mm, 10, 7}, 1000, "N10"}});
    // The tip is 0.5 mm into the box at t = 1.5 mm / (1000/60 mm/s) = 0.09 s and 3 mm in at 0.24 s.
    for (Device device : devices_to_test("the plunge test")) {
        force_model::PredictOptions o;
        o.device = device;
        const auto p = force_model::predict(m, spec, o);
        double fz_N = 0, torque_Nm = 0, fxy_max_N = 0;
        int n = 0;
        for (const auto& s : p.samples) {
            if (s.t_s < 0.10 || s.t_s > 0.23) continue;
            fz_N += s.fz_N;
            torque_Nm += s.torque_Nm;
            fxy_max_N = std::max(fxy_max_N, std::hypot(double(s.fx_N), double(s.fy_N)));
            ++n;
        }
        REQUIRE(n > 1000);
        fz_N /= n;
        torque_Nm /= n;
        INFO(name(device) << ": mean Fz " << fz_N << " N (expected " << fz_expected_N << "), torque "
                          << torque_Nm << " Nm (expected " << torque_expected_Nm << "), max |Fxy| " << fxy_max_N);
        CHECK(fz_N == Approx(fz_expected_N).epsilon(0.02));
        CHECK(torque_Nm == Approx(torque_expected_Nm).epsilon(0.02));
        // Two opposite straight flutes: the tangential and radial bottom forces cancel.
        CHECK(fxy_max_N < 0.02 * fz_expected_N);
    }
}
