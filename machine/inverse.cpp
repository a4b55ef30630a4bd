// Inverse kinematics of the nominal chain: tool tip and axis in workpiece coordinates -> axis
// positions. The rotary axes alone decide the tool axis, so they are solved first, in closed form
// (the two-rotation problem: the tool axis turned by the distal rotary axis must lie on the cone
// the proximal one sweeps, after Paden and Kahan's subproblems); with the rotations fixed the tip is
// affine in the linear positions, so those follow from one 3x3 solve. Unlike the thesis's
// closed form for its CAYXZ machine (eqs. 3.13-3.15), this holds for any pivots, axis directions
// (a 45 deg nutating head) and chain order.
#include "machine/kinematics.hpp"
#include "stages.hpp"

#include <fmt/format.h>

#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <optional>
#include <vector>

namespace cutload::machine {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kRadToDeg = 180 / kPi;
// Below this (a sine), an angle is undetermined: the vector to turn lies on the axis.
constexpr double kSingular = 1e-9;
// Round-off allowed at a travel limit (a pose computed at the limit comes back a hair outside).
constexpr double kLimitSlack = 1e-7;

// The angle that turns p onto q about the unit axis u, when both make the same angle with u
// (Paden-Kahan subproblem 1); nullopt when p lies on the axis (any angle will do).
std::optional<double> turn_angle(const Eigen::Vector3d& u, const Eigen::Vector3d& p, const Eigen::Vector3d& q) {
    const Eigen::Vector3d pp = p - u.dot(p) * u;
    const Eigen::Vector3d qq = q - u.dot(q) * u;
    if (pp.norm() < kSingular || qq.norm() < kSingular) return std::nullopt;
    return std::atan2(u.dot(pp.cross(qq)), pp.dot(qq));
}

std::string vec_text(const Eigen::Vector3d& v) { return fmt::format("({:.6g}, {:.6g}, {:.6g})", v.x(), v.y(), v.z()); }

// The logged value of rotation theta_rad nearest `previous` among its 360 deg equivalents within
// the axis's limits; nullopt when none is within them.
std::optional<double> nearest_within_limits(const Axis& a, double theta_rad, double previous) {
    const double q = a.sense * theta_rad * kRadToDeg;
    double k = std::round((previous - q) / 360);
    if (std::isfinite(a.lower) || std::isfinite(a.upper)) {
        const double kmin = std::isfinite(a.lower) ? std::ceil((a.lower - kLimitSlack - q) / 360) : -1e18;
        const double kmax = std::isfinite(a.upper) ? std::floor((a.upper + kLimitSlack - q) / 360) : 1e18;
        if (kmin > kmax) return std::nullopt;
        k = std::clamp(k, kmin, kmax);
    }
    return std::clamp(q + 360 * k, a.lower, a.upper);
}

struct RotarySolution {
    std::vector<std::optional<double>> theta_rad;   // per rotary axis; nullopt: undetermined
};

// Rotations (in chain order) turning the spindle axis a0 onto aW.
std::vector<RotarySolution> solve_rotations(const std::vector<const Axis*>& rot, const Eigen::Vector3d& a0,
                                            const Eigen::Vector3d& aW) {
    std::vector<RotarySolution> out;
    if (rot.empty()) {
        if ((aW - a0).norm() > 1e-9)
            throw KinematicsError(fmt::format("tool axis {}: a machine without rotary axes holds the tool along {}",
                                              vec_text(aW), vec_text(a0)));
        out.push_back({});
        return out;
    }
    if (rot.size() == 1) {
        const Eigen::Vector3d& u = rot[0]->direction;
        if (std::abs(u.dot(aW) - u.dot(a0)) > 1e-9)
            throw KinematicsError(fmt::format("tool axis {}: out of reach of rotary axis {} alone (it keeps the angle "
                                              "to its line at {:.6g} deg)",
                                              vec_text(aW), rot[0]->name, std::acos(std::clamp(u.dot(a0), -1.0, 1.0)) * kRadToDeg));
        out.push_back({{turn_angle(u, a0, aW)}});
        return out;
    }
    // R(u1, t1) R(u2, t2) a0 = aW. The middle vector z = R(u2, t2) a0 = R(u1, -t1) aW keeps its
    // angle to u2 (from a0) and to u1 (from aW): z = alpha u1 + beta u2 + gamma (u1 x u2).
    const Eigen::Vector3d& u1 = rot[0]->direction;
    const Eigen::Vector3d& u2 = rot[1]->direction;
    const Eigen::Vector3d n = u1.cross(u2);
    const double c = u1.dot(u2), s2 = n.squaredNorm();
    const double b1 = u1.dot(aW), b2 = u2.dot(a0);
    const double alpha = (b1 - c * b2) / s2, beta = (b2 - c * b1) / s2;
    // gamma^2 s2^2 = Gram determinant of (u1, u2, z), written as |u1 x aW|^2 s2 - (b2 - c b1)^2 so
    // that a tool axis near u1 keeps its digits (1 - b1^2 would cancel).
    const double gram = u1.cross(aW).squaredNorm() * s2 - (b2 - c * b1) * (b2 - c * b1);
    if (gram < -1e-12)
        throw KinematicsError(fmt::format("tool axis {}: out of reach of rotary axes {} and {} (no rotation of {} "
                                          "turns the spindle axis onto it)",
                                          vec_text(aW), rot[0]->name, rot[1]->name, rot[1]->name));
    const double gamma = std::sqrt(std::max(gram, 0.0)) / s2;
    for (const double sign : {1.0, -1.0}) {
        if (sign < 0 && gamma == 0) break;
        const Eigen::Vector3d z = alpha * u1 + beta * u2 + sign * gamma * n;
        out.push_back({{turn_angle(u1, z, aW), turn_angle(u2, a0, z)}});
    }
    return out;
}

}  // namespace

AxisPositions inverse(const Machine& m, const Eigen::Vector3d& tip_mm, const Eigen::Vector3d& axis,
                      double tool_length_mm, const AxisPositions& previous) {
    const double an = axis.norm();
    if (!(an > 0.5 && an < 1.5) || !tip_mm.allFinite())
        throw KinematicsError(fmt::format("target tip {} axis {}: the axis must be a unit vector and all values finite",
                                          vec_text(tip_mm), vec_text(axis)));
    const Eigen::Vector3d aW = axis / an;

    std::vector<std::size_t> rot_index;
    std::vector<const Axis*> rot;
    for (std::size_t i = 0; i < m.chain.size(); ++i)
        if (m.chain[i].rotary()) {
            rot_index.push_back(i);
            rot.push_back(&m.chain[i]);
        }
    const std::vector<RotarySolution> solutions = solve_rotations(rot, m.spindle.axis, aW);

    // Of the branches whose angles fit the limits, the one nearest the previous position.
    std::optional<AxisPositions> best;
    double best_distance = 0;
    std::string why_not;
    for (const RotarySolution& sol : solutions) {
        AxisPositions q = previous;
        double distance = 0;
        bool fits = true;
        for (std::size_t r = 0; r < rot.size(); ++r) {
            const std::size_t i = rot_index[r];
            const double prev = previous.value[i];
            // Undetermined: keep the previous angle (it still has to be within limits).
            const double theta = sol.theta_rad[r] ? *sol.theta_rad[r] : rot[r]->sense * prev / kRadToDeg;
            const std::optional<double> v = nearest_within_limits(*rot[r], theta, prev);
            if (!v) {
                fits = false;
                why_not = fmt::format("axis {} would need {:.6g} deg (mod 360), outside its limits [{:.6g}, {:.6g}]",
                                      rot[r]->name, rot[r]->sense * theta * kRadToDeg, rot[r]->lower, rot[r]->upper);
                break;
            }
            q.value[i] = *v;
            distance += (*v - prev) * (*v - prev);
        }
        if (fits && (!best || distance < best_distance)) {
            best = q;
            best_distance = distance;
        }
    }
    if (!best)
        throw KinematicsError(fmt::format("tool axis {}: {}", vec_text(aW), why_not));
    AxisPositions q = *best;

    // With the rotations fixed, tip(q_lin) = p0 + J q_lin exactly: each linear stage adds its
    // direction turned by the rotations before it in the chain.
    Eigen::Matrix3d J;
    std::size_t lin_index[3];
    int nl = 0;
    Eigen::Matrix3d R_before = Eigen::Matrix3d::Identity();
    for (std::size_t i = 0; i < m.chain.size(); ++i) {
        const Axis& a = m.chain[i];
        if (a.rotary()) {
            R_before = R_before * detail::axis_motion(a, q.value[i]).R;
        } else {
            J.col(nl) = R_before * (a.sense * a.direction);
            lin_index[nl++] = i;
            q.value[i] = 0;
        }
    }
    const Eigen::Vector3d p0 = forward(m, q, tool_length_mm, ErrorMode::Nominal).tip_mm();
    const Eigen::Vector3d lin = J.fullPivLu().solve(tip_mm - p0);
    for (int k = 0; k < 3; ++k) {
        const Axis& a = m.chain[lin_index[k]];
        double v = lin[k];
        if (v < a.lower - kLimitSlack || v > a.upper + kLimitSlack)
            throw KinematicsError(fmt::format("tool tip {} axis {}: axis {} would need {:.6f} mm, outside its limits "
                                              "[{:.6g}, {:.6g}]",
                                              vec_text(tip_mm), vec_text(aW), a.name, v, a.lower, a.upper));
        q.value[lin_index[k]] = std::clamp(v, a.lower, a.upper);
    }
    return q;
}

}  // namespace cutload::machine
