// Internal: quantities derived from a step's forces and moments (docs/force_model.md, "Conventions").
#pragma once

#include <cmath>
#include <numbers>

namespace cutload::force_model {

// Spindle power P = T omega.
inline float spindle_power_kW(float torque_Nm, double rpm) {
    return float(double(torque_Nm) * 2 * std::numbers::pi * std::abs(rpm) / 60 / 1000);
}

// Section modulus of a round shank, W = pi d^3 / 32.
inline double shank_section_modulus_mm3(double diameter_mm) {
    const double d = diameter_mm;
    return std::numbers::pi * d * d * d / 32;
}

// Bending stress sigma = |M| / W from the moment about the holder face.
inline float bending_stress_MPa(float mx_Nmm, float my_Nmm, double section_modulus_mm3) {
    return float(std::sqrt(double(mx_Nmm) * mx_Nmm + double(my_Nmm) * my_Nmm) / section_modulus_mm3);
}

}  // namespace cutload::force_model
