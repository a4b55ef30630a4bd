// Velocities of the tool relative to the workpiece from two poses over an interval (document 000,
// eqs. 3.16-3.22; docs/five_axis.md, "Velocities").
//
// The thesis writes the tool frame's rigid-body velocity as v_T = tau + omega x r_T (eq. 3.17),
// with tau = A^T d(r)/dt (3.18) and omega from the skew part of A^T dA/dt (3.19), A and r the
// rotation block and translation column of the tool-to-workpiece transform (3.20, 3.21). A log
// gives poses at unequal instants, not derivatives, so the twist of an interval is the constant
// body twist that carries the first pose exactly onto the second (the matrix logarithm of
// T_k^-1 T_k+1, divided by the interval): exact for a constant-rate rotation about a fixed line
// with any translation along it, and a second-order estimate of the mid-interval twist otherwise.
#pragma once

#include "machine/frame.hpp"

namespace cutload::machine {

// Body twist: both vectors in tool coordinates (the thesis's tau_Sigma and omega_Sigma).
struct Twist {
    Eigen::Vector3d v_mm_s = Eigen::Vector3d::Zero();       // velocity of the tool frame's origin (the tip)
    Eigen::Vector3d omega_rad_s = Eigen::Vector3d::Zero();  // angular velocity
};

// The twist that moves `from` onto `to` in dt_s (> 0; throws std::invalid_argument otherwise).
Twist interval_twist(const Frame& from, const Frame& to, double dt_s);

// Velocity of the tool point r_tool_mm (tool coordinates) relative to the workpiece, in tool
// coordinates (eq. 3.17).
Eigen::Vector3d point_velocity(const Twist& twist, const Eigen::Vector3d& r_tool_mm);

// The pose t_s after `from` along the twist's screw motion (advance(from, interval_twist(from, to,
// dt), dt) == to).
Frame advance(const Frame& from, const Twist& twist, double t_s);

// Velocity of the tool point r_tool_mm in workpiece coordinates at a pose `at` on the interval's
// screw motion: at.R * point_velocity(...). The body twist is the same all along the screw.
Eigen::Vector3d point_velocity_workpiece(const Frame& at, const Twist& twist, const Eigen::Vector3d& r_tool_mm);

}  // namespace cutload::machine
