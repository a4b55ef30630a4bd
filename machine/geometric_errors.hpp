// Geometric errors of one machine axis, as small rigid transforms inserted into the kinematic chain
// (document 000, section 3.4.2; ISO 230-1 names). See docs/machines.md, "Geometric errors".
//
// Six numbers describe a small rigid displacement: three translations along the machine's X, Y, Z
// and three rotations about them. Component errors are functions of the axis's own position
// (constant or a table, interpolated); location errors are constants. Both are displacements of
// everything the axis carries toward the tool, relative to the chain element before it (toward the
// workpiece), with the thesis's signs (eqs. 3.32, 3.34, 3.40, 3.42).
#pragma once

#include "machine/frame.hpp"

#include <array>
#include <optional>
#include <vector>

namespace cutload::machine {

// Index of an error component: translation along X, Y, Z (mm), rotation about X, Y, Z (rad).
// ISO 230-1 letters: E{X,Y,Z,A,B,C}<axis> for component errors, E{X,Y,Z,A,B,C}0<axis> for
// location errors.
enum ErrorComponent : int { kErrX = 0, kErrY, kErrZ, kErrA, kErrB, kErrC };
inline constexpr int kErrorComponents = 6;

// One component error against axis position. Values are mm (translations) or rad (rotations);
// positions are the axis's logged unit (mm or deg). One point: a constant. Between points: linear
// interpolation. Outside the table: the end value holds, except on a periodic table (a rotary
// axis measured over exactly one turn), which wraps.
struct ErrorTable {
    std::vector<double> at;       // strictly increasing
    std::vector<double> value;
    bool periodic = false;        // at.back() - at.front() == 360 deg, value.back() == value.front()

    double operator()(double position) const;
};

struct AxisErrors {
    std::array<std::optional<ErrorTable>, kErrorComponents> component;  // unset: zero
    std::array<double, kErrorComponents> location{};                   // mm, mm, mm, rad, rad, rad
    // The point about which the rotations act, in home coordinates at axis position 0 (rotary
    // axes: a point on the axis line, the pivot unless given). For a linear axis the component
    // errors' point travels with the axis; location errors stay at this point.
    Eigen::Vector3d reference_point_mm = Eigen::Vector3d::Zero();

    bool any() const;
};

// The rigid displacement with translation t_mm and rotation vector r_rad about the point c_mm:
// x -> c + t + exp(r) (x - c). To first order this is the thesis's I + epsilon (eqs. 3.32, 3.34);
// the exact rotation keeps the chain's rotation blocks orthonormal, which the twist needs.
Frame small_displacement(const Eigen::Vector3d& t_mm, const Eigen::Vector3d& r_rad, const Eigen::Vector3d& c_mm);

}  // namespace cutload::machine
