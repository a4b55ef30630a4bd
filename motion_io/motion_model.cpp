#include "motion_io/hermite.hpp"
#include "motion_io/motion_io.hpp"

#include <cmath>

namespace cutload::motion_io {

MotionState sample_between(const MotionModel& m, std::size_t i, double t_s) {
    // Cubic Hermite on position with the stored velocities as end slopes: C1 across samples,
    // so feed per tooth has no kinks at sample boundaries.
    const double t0 = m.t_s[i], t1 = m.t_s[i + 1];
    const double h = t1 - t0;
    const double u = h > 0 ? (t_s - t0) / h : 0.0;

    const std::vector<double>* p[3] = {&m.x_mm, &m.y_mm, &m.z_mm};
    const std::vector<double>* v[3] = {&m.vx_mm_s, &m.vy_mm_s, &m.vz_mm_s};
    MotionState s;
    s.t_s = t_s;
    for (int k = 0; k < 3; ++k) {
        const HermiteSegment seg{(*p[k])[i], (*v[k])[i], (*p[k])[i + 1], (*v[k])[i + 1], h};
        s.pos_mm[k] = seg.position(u);
        s.vel_mm_s[k] = seg.velocity(u);
    }
    // Spindle speed is linear between samples, so the angle (its integral) is quadratic: exact
    // for a linearly changing speed and consistent with the stored angles at both ends.
    const double r0 = m.spindle_rpm[i], r1 = m.spindle_rpm[i + 1];
    s.spindle_rpm = r0 + (r1 - r0) * u;
    const double dt = t_s - t0;
    s.spindle_angle_deg = m.spindle_angle_deg[i] + 6.0 * (r0 * dt + 0.5 * (r1 - r0) * u * dt);
    for (std::size_t k = 0; k < 3; ++k) {
        if (m.rot_deg[k].empty()) continue;
        const HermiteSegment seg{m.rot_deg[k][i], m.rot_vel_deg_s[k][i], m.rot_deg[k][i + 1], m.rot_vel_deg_s[k][i + 1], h};
        s.rot_deg[k] = seg.position(u);
        s.rot_vel_deg_s[k] = seg.velocity(u);
    }
    s.block = u < 0.5 ? m.block[i] : m.block[i + 1];
    if (i + 1 < m.tool.size()) s.tool = u < 0.5 ? m.tool[i] : m.tool[i + 1];
    return s;
}

}  // namespace cutload::motion_io
