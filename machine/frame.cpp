#include "machine/frame.hpp"

#include <cmath>

namespace cutload::machine {

Frame operator*(const Frame& a, const Frame& b) {
    return {a.R * b.R, a.R * b.origin_mm + a.origin_mm};
}

Frame inverse(const Frame& f) {
    const Eigen::Matrix3d Rt = f.R.transpose();
    return {Rt, -(Rt * f.origin_mm)};
}

Frame translation(const Eigen::Vector3d& d_mm) { return {Eigen::Matrix3d::Identity(), d_mm}; }

Eigen::Matrix3d skew(const Eigen::Vector3d& a) {
    Eigen::Matrix3d S;
    S << 0, -a.z(), a.y(),
         a.z(), 0, -a.x(),
         -a.y(), a.x(), 0;
    return S;
}

Eigen::Matrix3d rotation_about(const Eigen::Vector3d& u, double angle_rad) {
    return Eigen::AngleAxisd(angle_rad, u).toRotationMatrix();
}

Frame rotation_about_line(const Eigen::Vector3d& u, const Eigen::Vector3d& point_mm, double angle_rad) {
    const Eigen::Matrix3d R = rotation_about(u, angle_rad);
    return {R, point_mm - R * point_mm};
}

Eigen::Matrix3d exp_so3(const Eigen::Vector3d& rotation_vector_rad) {
    const double angle = rotation_vector_rad.norm();
    if (angle == 0) return Eigen::Matrix3d::Identity();
    return Eigen::AngleAxisd(angle, rotation_vector_rad / angle).toRotationMatrix();
}

Eigen::Vector3d log_so3(const Eigen::Matrix3d& R) {
    // Through the quaternion: its vector part is sin(angle/2) * axis, computed from differences of
    // off-diagonal entries, so small angles keep their full relative precision (acos of the trace
    // would lose half the digits).
    const Eigen::AngleAxisd aa(R);
    return aa.angle() * aa.axis();
}

}  // namespace cutload::machine
