#include "machine/twist.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace cutload::machine {
namespace {

// For the rotation vector phi (angle theta = |phi|), the matrix V with exp of the twist
// (omega, v) * t having translation V(phi) v t, and its inverse:
//   V     = I + (1 - cos th) / th^2 [phi] + (th - sin th) / th^3 [phi]^2
//   V^-1  = I - [phi] / 2 + (1 / th^2) (1 - th sin th / (2 (1 - cos th))) [phi]^2
// The coefficients are 0/0 at th = 0; below 1e-3 rad their Taylor series are exact to double
// precision (the first dropped terms are below 1e-19).
Eigen::Matrix3d v_matrix(const Eigen::Vector3d& phi) {
    const double th = phi.norm();
    const Eigen::Matrix3d W = skew(phi);
    double a, b;
    if (th < 1e-3) {
        const double t2 = th * th;
        a = 0.5 - t2 / 24 + t2 * t2 / 720;
        b = 1.0 / 6 - t2 / 120 + t2 * t2 / 5040;
    } else {
        a = (1 - std::cos(th)) / (th * th);
        b = (th - std::sin(th)) / (th * th * th);
    }
    return Eigen::Matrix3d::Identity() + a * W + b * W * W;
}

Eigen::Matrix3d v_matrix_inverse(const Eigen::Vector3d& phi) {
    const double th = phi.norm();
    const Eigen::Matrix3d W = skew(phi);
    double c;
    if (th < 1e-3) {
        const double t2 = th * th;
        c = 1.0 / 12 + t2 / 720 + t2 * t2 / 30240;
    } else {
        c = (1 - th * std::sin(th) / (2 * (1 - std::cos(th)))) / (th * th);
    }
    return Eigen::Matrix3d::Identity() - 0.5 * W + c * W * W;
}

}  // namespace

Twist interval_twist(const Frame& from, const Frame& to, double dt_s) {
    if (!(dt_s > 0) || !std::isfinite(dt_s))
        throw std::invalid_argument("interval_twist: the interval must be positive, got " + std::to_string(dt_s) + " s");
    const Frame delta = inverse(from) * to;
    const Eigen::Vector3d phi = log_so3(delta.R);
    Twist tw;
    tw.omega_rad_s = phi / dt_s;
    tw.v_mm_s = v_matrix_inverse(phi) * delta.origin_mm / dt_s;
    return tw;
}

Eigen::Vector3d point_velocity(const Twist& twist, const Eigen::Vector3d& r_tool_mm) {
    return twist.v_mm_s + twist.omega_rad_s.cross(r_tool_mm);
}

Frame advance(const Frame& from, const Twist& twist, double t_s) {
    const Eigen::Vector3d phi = twist.omega_rad_s * t_s;
    const Frame step{exp_so3(phi), v_matrix(phi) * twist.v_mm_s * t_s};
    return from * step;
}

Eigen::Vector3d point_velocity_workpiece(const Frame& at, const Twist& twist, const Eigen::Vector3d& r_tool_mm) {
    return at.R * point_velocity(twist, r_tool_mm);
}

}  // namespace cutload::machine
