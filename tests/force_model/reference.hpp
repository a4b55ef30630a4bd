// Independent reference for the force engine's physics tests: the mechanistic milling model of
// Altintas (Manufacturing Automation, 2nd ed., 2012, ch. 2) for a flat helical end mill cutting a
// straight path at constant feed, written without looking at the engine.
//
// Convention (the engine's public contract): forces act on the TOOL, feed along +X, spindle M03
// (clockwise seen from the spindle, looking down -Z), right-hand cutter. The immersion angle phi is
// measured clockwise from +Y, so a cutting point sits at R (sin phi, cos phi) and the chip is
// h = c sin(phi). Per unit axial length:
//   Fx = -Ft cos(phi) - Fr sin(phi),  Fy = Ft sin(phi) - Fr cos(phi),  Fz = Fa,  T = R Ft,
//   Ft = Ktc h + Kte,  Fr = Krc h + Kre,  Fa = Kac h + Kae.
#pragma once

#include "force_model/force_model.hpp"
#include "force_model/motion_fixtures.hpp"

#include <cstddef>
#include <functional>
#include <string>
#include <vector>

namespace cutload::testref {

struct Coefficients {
    double Ktc_N_mm2 = 0, Krc_N_mm2 = 0, Kac_N_mm2 = 0;
    double Kte_N_mm = 0, Kre_N_mm = 0, Kae_N_mm = 0;
};

// The same coefficients with the edge (K.e) or the chip-area (K.c) terms switched off.
Coefficients cutting_part(const Coefficients& k);
Coefficients edge_part(const Coefficients& k);

struct Cut {
    double diameter_mm = 8;
    int flutes = 2;
    double helix_deg = 30;
    double axial_depth_mm = 2;
    double feed_per_tooth_mm = 0.1;
    double phi_start_rad = 0;   // immersion window [phi_start, phi_exit], 0 <= start < exit <= pi
    double phi_exit_rad = 0;
};

struct Forces {
    double fx_N = 0, fy_N = 0, fz_N = 0;
    double torque_Nm = 0;   // positive: the cut resists the M03 rotation
};

// Immersion windows (Altintas ch. 2): up milling cuts from phi = 0, down milling exits at phi = pi.
double up_milling_exit_rad(double radial_depth_mm, double diameter_mm);
double down_milling_start_rad(double radial_depth_mm, double diameter_mm);
Cut slot_cut(double diameter_mm, int flutes, double helix_deg, double axial_mm, double feed_per_tooth_mm);
Cut up_cut(double diameter_mm, int flutes, double helix_deg, double axial_mm, double feed_per_tooth_mm,
           double radial_mm);
Cut down_cut(double diameter_mm, int flutes, double helix_deg, double axial_mm, double feed_per_tooth_mm,
             double radial_mm);

// Closed-form average over one tooth period; the helix does not change it.
Forces average_forces(const Cut& cut, const Coefficients& k);

// Instantaneous forces by numerical integration along the flutes: flute 0's tip at immersion
// phi_tool_rad, axial slices of a_p / axial_slices with the helix lag 2 z tan(beta) / D, engagement
// decided from the immersion window alone.
Forces instantaneous_forces(const Cut& cut, const Coefficients& k, double phi_tool_rad, int axial_slices = 400);

// The same integration where the stock's edges do not run along the feed: slice z_mm (above the
// tip) of a flute at immersion phi_rad (in [0, 2 pi)) cuts where `cuts(phi_rad, z_mm)` says, with
// the chip c sin(phi); the cut's immersion window is not used.
Forces instantaneous_forces_where(const Cut& cut, const Coefficients& k, double phi_tool_rad, int axial_slices,
                                  const std::function<bool(double phi_rad, double z_mm)>& cuts);

// One slice dz of a revolved flank at radius r whose cutting edge leans from the axis (sin and cos
// of the lean sb, cb), cutting a box whose face is d from the axis: Altintas' edge forces turned out
// of the edge's normal plane, integrated over the immersion by the midpoint rule (up milling from
// phi = 0, down milling up to pi) and added to `sum` per radian of tool turn. The tapered and
// barrel reference integrations differ only in how r and the lean change along the axis.
void add_flank_slice(Forces& sum, const Coefficients& k, double r, double d, double sb, double cb, bool up,
                     double feed_per_tooth_mm, double dz, int phi_steps);

double resultant_N(const Forces& f);
// |a - b| over the three force components, relative to |b|.
double relative_force_error(const Forces& a, const Forces& b);

// Coefficients of the order of an aluminium alloy, chosen for testing (not a published set): every
// term non-zero so that a dropped or mis-signed term shows.
inline Coefficients test_coefficients() { return {700.0, 210.0, 120.0, 20.0, 28.0, 2.0}; }

// ---- Harness: run specs for the reference cut and analysis of predict() output ----------------

force_model::RunSpec flat_tool_spec(const Cut& cut, const Coefficients& k, const force_model::StockBox& box,
                                    double grid_mm);

// A straight cut at constant feed through a box whose faces produce exactly the cut's immersion
// window: the tool enters from outside, cuts `steady_mm` of steady state and stops in the
// material. quarter_turns rotates the whole set-up (path and box) by 90 degrees counter-clockwise
// about Z per turn, so the feed runs along +X, +Y, -X or -Y.
struct StraightSetup {
    Path path;
    force_model::StockBox box;
    double steady_t0_s = 0, steady_t1_s = 0;   // the tool centre is past entry and before the end
};
StraightSetup straight_setup(const Cut& cut, double spindle_rpm, int quarter_turns = 0, double steady_mm = 4.0);

// Rotates a force vector (torque unchanged) by quarter_turns x 90 degrees counter-clockwise about Z.
Forces rotate_quarter_turns(const Forces& f, int quarter_turns);

// Devices to run: Cpu always, OpenCL when an OpenCL platform exists (else a WARN says it was skipped).
std::vector<force_model::Device> devices_under_test();
const char* device_name(force_model::Device d);

// Measured figures go to stdout when CUTLOAD_PHYS_VERBOSE is set (for reports); tests stay quiet.
void report_figure(const std::string& line);

// Mean of the engine's samples with t in [t0_s, t1_s] over a whole number of tooth periods of
// spindle angle (trapezoids in angle, so uneven row spacing does not bias it).
struct SteadyMean {
    Forces forces;
    double power_kW = 0;
    int tooth_periods = 0;
    std::size_t samples = 0;
    double max_angle_gap_deg = 0;   // largest spindle-angle step between rows in the window
};
SteadyMean steady_mean(const std::vector<force_model::ForceSample>& samples, double t0_s, double t1_s, int flutes);

// The engine's trace in [t0_s, t1_s] against instantaneous_forces(). The engine's spindle angle has
// no published zero, so flute 0's immersion is taken as (spindle angle + offset) and the offset is
// fitted. rms_rel: RMS of the force-vector difference over the window / peak reference resultant;
// torque_rms_rel likewise for torque.
struct TraceFit {
    double rms_rel = 0, torque_rms_rel = 0;
    double offset_deg = 0;
    double peak_reference_N = 0;
    std::size_t samples = 0;
};
TraceFit fit_trace(const std::vector<force_model::ForceSample>& samples, double t0_s, double t1_s, const Cut& cut,
                   const Coefficients& k);

}  // namespace cutload::testref
