// Motion fixtures for the force engine's physics tests: exact paths made of straight lines and
// arcs in the XY plane at constant feed and spindle speed, either as a uniform MotionModel (what
// ingest hands the engine) or as a raw CSV log in the seed's irregular sampling pattern (what a
// dry run records), so both routes can be compared.
#pragma once

#include "motion_io/motion_io.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <numbers>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

namespace cutload::testref {

using Vec3 = std::array<double, 3>;

struct PathSegment {
    enum class Kind { Line, Arc } kind = Kind::Line;
    Vec3 end_mm{};
    double center_x_mm = 0, center_y_mm = 0;   // arcs only; z stays constant along an arc
    bool ccw = true;                            // arcs only, seen from +Z
    std::string block;
};

inline PathSegment line_to(Vec3 end_mm, std::string block) {
    PathSegment s;
    s.end_mm = end_mm;
    s.block = std::move(block);
    return s;
}

inline PathSegment arc_to(Vec3 end_mm, double center_x_mm, double center_y_mm, bool ccw, std::string block) {
    PathSegment s;
    s.kind = PathSegment::Kind::Arc;
    s.end_mm = end_mm;
    s.center_x_mm = center_x_mm;
    s.center_y_mm = center_y_mm;
    s.ccw = ccw;
    s.block = std::move(block);
    return s;
}

// A tool path driven at constant path feed and spindle speed from start_mm through the segments.
struct Path {
    Vec3 start_mm{};
    std::vector<PathSegment> segments;
    double feed_mm_min = 2000;
    double spindle_rpm = 10000;
};

// One layer of zig-zag pocketing at height z: in at x = -6, five passes along x between x_lo and
// x_hi, `stepover_mm` apart from y0 up, joined by half-circle turns (so later passes cut against
// the walls the earlier ones left, round ones included), and out at x = -6. Blocks are named
// "<name> entry", "<name> pass k", "<name> turn k", "<name> exit".
inline void add_zigzag_layer(Path& p, double z, const std::string& name, double y0, double stepover_mm, double x_lo,
                             double x_hi) {
    double y = y0;
    p.segments.push_back(line_to({-6, y, z}, name + " entry"));
    for (int pass = 0; pass < 5; ++pass) {
        const bool forward = pass % 2 == 0;
        const double x_end = forward ? x_hi : x_lo;
        p.segments.push_back(line_to({x_end, y, z}, name + " pass " + std::to_string(pass)));
        p.segments.push_back(
            arc_to({x_end, y + stepover_mm, z}, x_end, y + stepover_mm / 2, forward, name + " turn " + std::to_string(pass)));
        y += stepover_mm;
    }
    p.segments.push_back(line_to({-6, y, z}, name + " exit"));
}

struct PathState {
    Vec3 pos_mm{}, vel_mm_s{};
    std::size_t segment = 0;
};

namespace detail {

struct ArcGeometry {
    double radius_mm, start_angle_rad, sweep_rad;
};

inline ArcGeometry arc_geometry(const Vec3& from, const PathSegment& s) {
    const double a0 = std::atan2(from[1] - s.center_y_mm, from[0] - s.center_x_mm);
    const double a1 = std::atan2(s.end_mm[1] - s.center_y_mm, s.end_mm[0] - s.center_x_mm);
    const double two_pi = 2 * std::numbers::pi;
    double sweep = a1 - a0;
    if (s.ccw) {
        while (sweep <= 0) sweep += two_pi;
    } else {
        while (sweep >= 0) sweep -= two_pi;
    }
    return {std::hypot(from[0] - s.center_x_mm, from[1] - s.center_y_mm), a0, sweep};
}

inline double segment_length_mm(const Vec3& from, const PathSegment& s) {
    if (s.kind == PathSegment::Kind::Line)
        return std::hypot(s.end_mm[0] - from[0], s.end_mm[1] - from[1], s.end_mm[2] - from[2]);
    const ArcGeometry g = arc_geometry(from, s);
    return g.radius_mm * std::abs(g.sweep_rad);
}

}  // namespace detail

inline double path_length_mm(const Path& p) {
    double total = 0;
    Vec3 from = p.start_mm;
    for (const PathSegment& s : p.segments) {
        total += detail::segment_length_mm(from, s);
        from = s.end_mm;
    }
    return total;
}

inline double path_duration_s(const Path& p) { return path_length_mm(p) / (p.feed_mm_min / 60.0); }

// Exact position and velocity at time t_s (clamped to the path's ends; at rest after the end).
inline PathState path_state(const Path& p, double t_s) {
    const double speed_mm_s = p.feed_mm_min / 60.0;
    double s_mm = std::max(0.0, t_s) * speed_mm_s;
    Vec3 from = p.start_mm;
    for (std::size_t i = 0; i < p.segments.size(); ++i) {
        const PathSegment& seg = p.segments[i];
        const double len = detail::segment_length_mm(from, seg);
        if (s_mm <= len || i + 1 == p.segments.size()) {
            const bool past_end = s_mm > len;
            const double u = len > 0 ? std::min(s_mm, len) / len : 0.0;
            PathState st;
            st.segment = i;
            if (seg.kind == PathSegment::Kind::Line) {
                for (int k = 0; k < 3; ++k) {
                    st.pos_mm[k] = from[k] + u * (seg.end_mm[k] - from[k]);
                    st.vel_mm_s[k] = past_end || len == 0 ? 0.0 : speed_mm_s * (seg.end_mm[k] - from[k]) / len;
                }
            } else {
                const detail::ArcGeometry g = detail::arc_geometry(from, seg);
                const double a = g.start_angle_rad + u * g.sweep_rad;
                const double dir = g.sweep_rad > 0 ? 1.0 : -1.0;
                st.pos_mm = {seg.center_x_mm + g.radius_mm * std::cos(a), seg.center_y_mm + g.radius_mm * std::sin(a),
                             from[2]};
                st.vel_mm_s = {past_end ? 0.0 : -dir * speed_mm_s * std::sin(a),
                               past_end ? 0.0 : dir * speed_mm_s * std::cos(a), 0.0};
            }
            return st;
        }
        s_mm -= len;
        from = seg.end_mm;
    }
    throw std::invalid_argument("path_state: path has no segments");
}

// Uniform motion model (step_s, default 1 ms) sampled exactly from the path, spindle angle
// integrated from the speed by the trapezoid rule; `offset_mm` is subtracted so the model holds
// machine positions when the run spec adds it back.
inline motion_io::MotionModel uniform_motion(const Path& p, double step_s = 0.001, Vec3 offset_mm = {0, 0, 0}) {
    motion_io::MotionModel m;
    m.step_s = step_s;
    for (const PathSegment& s : p.segments)
        if (std::find(m.block_names.begin(), m.block_names.end(), s.block) == m.block_names.end())
            m.block_names.push_back(s.block);
    const auto n = static_cast<std::size_t>(std::floor(path_duration_s(p) / step_s)) + 1;
    for (std::size_t i = 0; i < n; ++i) {
        const double t = static_cast<double>(i) * step_s;
        const PathState st = path_state(p, t);
        m.t_s.push_back(t);
        m.x_mm.push_back(st.pos_mm[0] - offset_mm[0]);
        m.y_mm.push_back(st.pos_mm[1] - offset_mm[1]);
        m.z_mm.push_back(st.pos_mm[2] - offset_mm[2]);
        m.vx_mm_s.push_back(st.vel_mm_s[0]);
        m.vy_mm_s.push_back(st.vel_mm_s[1]);
        m.vz_mm_s.push_back(st.vel_mm_s[2]);
        m.spindle_rpm.push_back(p.spindle_rpm);
        const double angle = i == 0 ? 0.0
                                    : m.spindle_angle_deg.back() +
                                          6.0 * 0.5 * (m.spindle_rpm[i - 1] + m.spindle_rpm[i]) * step_s;
        m.spindle_angle_deg.push_back(angle);
        const auto name = std::find(m.block_names.begin(), m.block_names.end(), p.segments[st.segment].block);
        m.block.push_back(static_cast<std::int32_t>(name - m.block_names.begin()));
    }
    m.session_start = {0};
    return m;
}

// Writes the path as a dry-run CSV log in the seed's pattern (seed 001, table 4.1 and fig. 4.9):
// a client cycle reads spindle, feed and position one after another (about 1.8, 2.0 and 2.25 ms,
// with jitter), each channel with its own time stamp, while the CNC updates its position on a
// 4 ms grid of its own phase, so some updates are read twice and some are missed. Positions are
// machine positions (path minus offset_mm) rounded to 1 um as the seed logged them. Each read's
// duration varies uniformly by +-jitter_ms / 2.
inline void write_seed_pattern_csv(const Path& p, const std::string& file, Vec3 offset_mm = {0, 0, 0},
                                   double jitter_ms = 0.3, unsigned seed = 7) {
    std::ofstream out(file);
    if (!out) throw std::runtime_error("cannot write " + file);
    std::mt19937 rng(seed);
    // Raw engine output scaled by hand: std distributions differ between standard libraries.
    auto jitter_s = [&] { return (static_cast<double>(rng()) / 4294967295.0 - 0.5) * jitter_ms * 1e-3; };
    const double cnc_period_s = 4e-3, cnc_phase_s = 1.3e-3;
    auto cnc_time = [&](double t_s) { return std::floor((t_s - cnc_phase_s) / cnc_period_s) * cnc_period_s + cnc_phase_s; };
    out << "t_spindle,spindle,t_feed,feed,t_pos,x,y,z,block\n";
    out.setf(std::ios::fixed);
    const double end_s = path_duration_s(p) + 0.02;
    for (double t = 0.0; t < end_s;) {
        const double t_spindle = t + 1.8e-3 + jitter_s();
        const double t_feed = t_spindle + 2.0e-3 + jitter_s();
        const double t_pos = t_feed + 2.25e-3 + jitter_s();
        const PathState feed_state = path_state(p, cnc_time(t_feed));
        const PathState pos_state = path_state(p, cnc_time(t_pos));
        const double feed = std::hypot(feed_state.vel_mm_s[0], feed_state.vel_mm_s[1], feed_state.vel_mm_s[2]) * 60.0;
        out.precision(6);
        out << t_spindle << ',';
        out.precision(1);
        out << p.spindle_rpm << ',';
        out.precision(6);
        out << t_feed << ',';
        out.precision(1);
        out << feed << ',';
        out.precision(6);
        out << t_pos << ',';
        out.precision(3);
        out << pos_state.pos_mm[0] - offset_mm[0] << ',' << pos_state.pos_mm[1] - offset_mm[1] << ','
            << pos_state.pos_mm[2] - offset_mm[2] << ',' << p.segments[pos_state.segment].block << '\n';
        t = t_pos;
    }
}

}  // namespace cutload::testref
