// Rigid frames and rotations: the value types every other part of machine/ is built on.
//
// A Frame maps coordinates in the frame to its parent: x_parent = R x_frame + origin_mm. Frames
// compose left to right along a kinematic chain, so a chain from the workpiece to the tool is one
// product whose result maps tool coordinates to workpiece coordinates (document 000, eq. 3.28).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace cutload::machine {

struct Frame {
    Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
    Eigen::Vector3d origin_mm = Eigen::Vector3d::Zero();
};

// a * b: first b, then a (b's parent is a's frame).
Frame operator*(const Frame& a, const Frame& b);
Frame inverse(const Frame& f);
inline Eigen::Vector3d apply(const Frame& f, const Eigen::Vector3d& p_mm) { return f.R * p_mm + f.origin_mm; }

Frame translation(const Eigen::Vector3d& d_mm);

// Right-handed rotation by angle_rad about the unit direction u (Rodrigues).
Eigen::Matrix3d rotation_about(const Eigen::Vector3d& u, double angle_rad);

// The same rotation as a Frame about the line through point_mm along u: points on the line stay.
Frame rotation_about_line(const Eigen::Vector3d& u, const Eigen::Vector3d& point_mm, double angle_rad);

// Rotation vector <-> rotation matrix (the exponential map of SO(3) and its inverse). The rotation
// vector's direction is the axis, its length the angle in rad; log_so3 returns angles in [0, pi].
Eigen::Matrix3d exp_so3(const Eigen::Vector3d& rotation_vector_rad);
Eigen::Vector3d log_so3(const Eigen::Matrix3d& R);

// Cross-product (skew) matrix: skew(a) * b == a.cross(b).
Eigen::Matrix3d skew(const Eigen::Vector3d& a);

}  // namespace cutload::machine
