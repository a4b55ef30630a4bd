// Forward kinematics: the product of the chain's stages (document 000, eq. 3.28), each with its
// axis's geometric errors (section 3.4.2) when asked for.
#include "machine/kinematics.hpp"
#include "stages.hpp"

namespace cutload::machine {

namespace detail {

constexpr double kDegToRad = 3.14159265358979323846 / 180;

Frame axis_motion(const Axis& a, double q) {
    const double s = a.sense * q;
    if (a.rotary()) return rotation_about_line(a.direction, a.pivot_mm, s * kDegToRad);
    return translation(s * a.direction);
}

namespace {

// The moving part of the axis relative to its carrier (the element toward the bed), as a small
// displacement: location errors first (where the axis sits on its carrier), then the component
// errors at this position (how it moves there). Directions are the carrier's.
Frame axis_error(const Axis& a, double q) {
    const AxisErrors& e = a.errors;
    const Eigen::Vector3d c0 = e.reference_point_mm;
    const Frame location = small_displacement(Eigen::Vector3d(e.location[0], e.location[1], e.location[2]),
                                              Eigen::Vector3d(e.location[3], e.location[4], e.location[5]), c0);
    double v[kErrorComponents];
    for (int i = 0; i < kErrorComponents; ++i) {
        const auto& table = e.component[static_cast<std::size_t>(i)];
        v[i] = table ? (*table)(q) : 0.0;
    }
    // A linear axis's reference point rides on its moving part. In carrier coordinates that is
    // +q along the axis for a head axis and -q for a table axis (the table moves the workpiece the
    // other way so that the tool moves +q relative to it).
    Eigen::Vector3d c = c0;
    if (!a.rotary()) c += (a.side == Side::Tool ? 1.0 : -1.0) * a.sense * q * a.direction;
    return location * small_displacement(Eigen::Vector3d(v[0], v[1], v[2]), Eigen::Vector3d(v[3], v[4], v[5]), c);
}

}  // namespace

Frame stage(const Axis& a, double q, ErrorMode mode) {
    const Frame motion = axis_motion(a, q);
    if (mode == ErrorMode::Nominal || !a.errors.any()) return motion;
    // The chain runs from the workpiece to the tool. A head axis's carrier lies on its workpiece
    // side (to the left of its motion); a table axis's carrier lies on its tool side (to the right),
    // and the stage maps the carrier into the moving part, hence the inverse.
    const Frame err = axis_error(a, q);
    return a.side == Side::Tool ? err * motion : motion * inverse(err);
}

Frame tool_at_home(const Spindle& s, double tool_length_mm) {
    Frame f;
    f.R.col(0) = s.x_direction;
    f.R.col(1) = s.axis.cross(s.x_direction);
    f.R.col(2) = s.axis;
    f.origin_mm = s.gauge_point_mm - tool_length_mm * s.axis;
    return f;
}

}  // namespace detail

AxisPositions positions(const Machine& m, const std::map<char, double>& by_name) {
    AxisPositions q;
    for (const auto& [name, value] : by_name) q.value[m.index_of(name)] = value;
    return q;
}

ToolPose forward(const Machine& m, const AxisPositions& q, double tool_length_mm, ErrorMode mode) {
    Frame t;
    for (std::size_t i = 0; i < m.chain.size(); ++i) t = t * detail::stage(m.chain[i], q.value[i], mode);
    return {t * detail::tool_at_home(m.spindle, tool_length_mm)};
}

Frame bed_to_workpiece(const Machine& m, const AxisPositions& q, ErrorMode mode) {
    Frame t;
    for (std::size_t i = 0; i < m.chain.size() && m.chain[i].side == Side::Workpiece; ++i)
        t = t * detail::stage(m.chain[i], q.value[i], mode);
    return t;
}

ToolAndBed forward_with_bed(const Machine& m, const AxisPositions& q, double tool_length_mm, ErrorMode mode) {
    // forward()'s loop split where bed_to_workpiece() stops (at the first stage not on the workpiece
    // side), so both results are the products those functions form, in their order.
    Frame t;
    std::size_t i = 0;
    for (; i < m.chain.size() && m.chain[i].side == Side::Workpiece; ++i) t = t * detail::stage(m.chain[i], q.value[i], mode);
    const Frame bed = t;
    for (; i < m.chain.size(); ++i) t = t * detail::stage(m.chain[i], q.value[i], mode);
    return {{t * detail::tool_at_home(m.spindle, tool_length_mm)}, bed};
}

}  // namespace cutload::machine
