#include "app/tool_centre_point.hpp"

#include "machine/kinematics.hpp"
#include "machine/machine.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

namespace cutload::app {
namespace {

using motion_io::NcAxes;
using motion_io::NcBlock;
using motion_io::NcToolPose;
using motion_io::ToolCentrePoint;

// Round-off allowed at a travel limit, as machine::inverse allows it.
constexpr double kLimitSlackDeg = 1e-7;

class MachineTcp final : public motion_io::ToolCentrePointKinematics {
public:
    MachineTcp(std::shared_ptr<const machine::Machine> m, double tool_length_mm) : m_(std::move(m)), length_mm_(tool_length_mm) {}

    NcToolPose forward(const NcAxes& q) const override {
        const machine::ToolPose pose = machine::forward(*m_, positions(q), length_mm_, machine::ErrorMode::Nominal);
        NcToolPose out;
        const Eigen::Vector3d axis = pose.axis();
        for (int k = 0; k < 3; ++k) out.tip_mm[std::size_t(k)] = pose.tip_mm()[k], out.axis[std::size_t(k)] = axis[k];
        return out;
    }

    NcAxes inverse(const NcToolPose& pose, const NcAxes& previous) const override {
        const Eigen::Vector3d tip(pose.tip_mm[0], pose.tip_mm[1], pose.tip_mm[2]);
        const Eigen::Vector3d axis(pose.axis[0], pose.axis[1], pose.axis[2]);
        return axes(machine::inverse(*m_, tip, axis, length_mm_, positions(previous)));
    }

    NcAxes with_rotary(const std::array<double, 3>& tip_mm, const std::array<double, 3>& rotary_deg) const override {
        // Commanded angles are taken as they are, so one outside the travel is the program's error,
        // not a cue to look for another solution.
        NcAxes at;
        at.rotary_deg = rotary_deg;
        for (const machine::Axis& a : m_->chain) {
            if (!a.rotary()) continue;
            const double v = rotary_deg[std::size_t(a.name - 'A')];
            if (v < a.lower - kLimitSlackDeg || v > a.upper + kLimitSlackDeg)
                throw machine::KinematicsError(fmt::format("axis {} at {:.6g} deg is outside its limits [{:.6g}, {:.6g}]", a.name, v,
                                                           a.lower, a.upper));
        }
        // The rotary angles fix the tool axis; inverse kinematics with them as the previous position
        // then keeps them (their own solution is nearest) and solves the linear axes for the tip.
        NcAxes q = inverse(NcToolPose{tip_mm, forward(at).axis}, at);
        q.rotary_deg = rotary_deg;
        return q;
    }

private:
    machine::AxisPositions positions(const NcAxes& q) const {
        machine::AxisPositions p;
        for (std::size_t k = 0; k < m_->chain.size(); ++k) {
            const machine::Axis& a = m_->chain[k];
            p.value[k] = a.rotary() ? q.rotary_deg[std::size_t(a.name - 'A')] : q.linear_mm[std::size_t(a.name - 'X')];
        }
        return p;
    }
    NcAxes axes(const machine::AxisPositions& p) const {
        NcAxes q;
        for (std::size_t k = 0; k < m_->chain.size(); ++k) {
            const machine::Axis& a = m_->chain[k];
            if (a.rotary()) q.rotary_deg[std::size_t(a.name - 'A')] = p.value[k];
            else q.linear_mm[std::size_t(a.name - 'X')] = p.value[k];
        }
        return q;
    }

    std::shared_ptr<const machine::Machine> m_;
    double length_mm_;
};

using Vec3 = std::array<double, 3>;

double dot(const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
double distance(const Vec3& a, const Vec3& b) { return std::hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]); }
double angle_rad(const Vec3& a, const Vec3& b) {
    // atan2 of |a x b| and a . b keeps its digits for nearly parallel axes (acos would not).
    const Vec3 c{a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
    return std::atan2(std::hypot(c[0], c[1], c[2]), dot(a, b));
}
Vec3 lerp(const Vec3& a, const Vec3& b, double u) { return {a[0] + u * (b[0] - a[0]), a[1] + u * (b[1] - a[1]), a[2] + u * (b[2] - a[2])}; }

// The unit vector at fraction u of the great circle from a to b (the parser refuses opposite axes).
Vec3 slerp(const Vec3& a, const Vec3& b, double u) {
    const double omega = angle_rad(a, b);
    if (omega < 1e-12) return a;
    const double s = std::sin(omega), wa = std::sin((1 - u) * omega) / s, wb = std::sin(u * omega) / s;
    Vec3 v{wa * a[0] + wb * b[0], wa * a[1] + wb * b[1], wa * a[2] + wb * b[2]};
    const double n = std::hypot(v[0], v[1], v[2]);
    return {v[0] / n, v[1] / n, v[2] / n};
}

NcAxes midpoint(const NcAxes& a, const NcAxes& b) {
    NcAxes m;
    m.linear_mm = lerp(a.linear_mm, b.linear_mm, 0.5);
    m.rotary_deg = lerp(a.rotary_deg, b.rotary_deg, 0.5);
    return m;
}

double axes_gap(const NcAxes& a, const NcAxes& b) {
    double gap = 0;
    for (std::size_t k = 0; k < 3; ++k)
        gap = std::max({gap, std::abs(a.linear_mm[k] - b.linear_mm[k]), std::abs(a.rotary_deg[k] - b.rotary_deg[k])});
    return gap;
}

// A point of the tool-centre-point path and the machine's axes there.
struct PathPoint {
    double u = 0;
    NcAxes q;
};

}  // namespace

std::shared_ptr<const motion_io::ToolCentrePointKinematics> tool_centre_point_kinematics(
    std::shared_ptr<const machine::Machine> machine, double tool_length_mm) {
    return std::make_shared<MachineTcp>(std::move(machine), tool_length_mm);
}

bool has_tool_centre_point(const motion_io::NcProgram& program) {
    return std::any_of(program.blocks.begin(), program.blocks.end(), [](const NcBlock& b) { return b.tcp != ToolCentrePoint::Off; });
}

motion_io::NcProgram machine_axis_program(const motion_io::NcProgram& program, const motion_io::ToolCentrePointKinematics& kinematics,
                                          const TcpPieceLimits& limits) {
    motion_io::NcProgram out = program;
    out.blocks.clear();
    auto where = [&](const NcBlock& b) { return fmt::format("{}:{}: block {}", program.file, b.line, b.name); };
    for (const NcBlock& b : program.blocks) {
        if (b.tcp == ToolCentrePoint::Off || !motion_io::block_moves(b)) {
            if (out.blocks.size() + 1 > limits.total)
                throw motion_io::NcProgramError(fmt::format("{}: the program needs more than {} pieces in machine-axis form in all "
                                                            "(split the program)", where(b), limits.total));
            NcBlock copy = b;
            copy.tcp = ToolCentrePoint::Off;
            out.blocks.push_back(std::move(copy));
            continue;
        }
        const bool vector = b.tcp == ToolCentrePoint::AxisVector;
        auto tip_at = [&](double u) { return lerp(b.tip_start_mm, b.tip_end_mm, u); };
        auto axis_at = [&](double u) { return slerp(b.axis_start, b.axis_end, u); };
        auto solve = [&](double u, const NcAxes& previous) {
            try {
                if (vector) return kinematics.inverse(NcToolPose{tip_at(u), axis_at(u)}, previous);
                return kinematics.with_rotary(tip_at(u), lerp(b.start_deg, b.end_deg, u));
            } catch (const std::exception& e) {
                const Vec3 tip = tip_at(u);
                throw motion_io::NcProgramError(fmt::format("{}: {:.4g} % into the block the machine cannot reach the tip ({:.6g}, {:.6g}, "
                                                            "{:.6g}): {}", where(b), 100 * u, tip[0], tip[1], tip[2], e.what()));
            }
        };
        // How far joint-space interpolation from a to b strays from the path at its midpoint um.
        auto off_path = [&](const PathPoint& a, const PathPoint& b_, const PathPoint& m) {
            const NcToolPose lin = kinematics.forward(midpoint(a.q, b_.q));
            const Vec3 axis = vector ? axis_at(m.u) : kinematics.forward(m.q).axis;
            return distance(lin.tip_mm, tip_at(m.u)) > kTcpTipTolMm || angle_rad(lin.axis, axis) > kTcpAxisTolRad;
        };

        // At least one piece per quarter turn of any rotary axis or of the tool axis, so a turn whose
        // ends look alike is never one chord; then bisection to the tolerance.
        double turn_deg = 0;
        for (std::size_t r = 0; r < 3; ++r) turn_deg = std::max(turn_deg, std::abs(b.end_deg[r] - b.start_deg[r]));
        if (vector) turn_deg = std::max(turn_deg, angle_rad(b.axis_start, b.axis_end) * 180.0 / std::numbers::pi);
        const auto initial = std::size_t(std::max(1.0, std::ceil(turn_deg / 90.0)));

        NcAxes start;
        start.linear_mm = b.start_mm;
        start.rotary_deg = b.start_deg;
        std::vector<PathPoint> points{{0.0, start}};
        auto too_many = [&](double u) {
            return motion_io::NcProgramError(fmt::format(
                "{}: joint-space interpolation needs more than {} pieces to stay within {} um of its tool-centre-point path (passed "
                "{:.3g} % into the block; the path passes near a singular orientation of the machine, or turns too far in one "
                "block: split it)",
                where(b), limits.per_block, kTcpTipTolMm * 1e3, 100 * u));
        };
        // Depth-first: each point is solved from the one before it on the path, as a controller
        // steps along the block, and the pieces are counted as they are made.
        auto refine = [&](auto&& self, const PathPoint& a, const PathPoint& e, int depth) -> void {
            PathPoint m{0.5 * (a.u + e.u), {}};
            m.q = solve(m.u, a.q);
            if (off_path(a, e, m)) {
                if (depth >= 16) throw too_many(m.u);
                self(self, a, m, depth + 1);
                const PathPoint left_end = points.back();
                PathPoint e2 = e;
                if (vector) e2.q = solve(e.u, left_end.q);   // the right half continues from where the left one ended
                self(self, left_end, e2, depth + 1);
                return;
            }
            if (points.size() > limits.per_block || out.blocks.size() + points.size() > limits.total) throw too_many(e.u);
            points.push_back(e);
        };
        for (std::size_t k = 0; k < initial; ++k) {
            const double u1 = double(k + 1) / double(initial);
            const PathPoint& a = points.back();
            refine(refine, a, PathPoint{u1, solve(u1, a.q)}, 0);
        }
        NcAxes end;
        end.linear_mm = b.end_mm;
        end.rotary_deg = b.end_deg;
        if (axes_gap(points.back().q, end) > 1e-6)
            throw motion_io::NcProgramError(fmt::format(
                "{}: stepping along the block the machine's axes end at ({:.6g}, {:.6g}, {:.6g}) mm, ({:.6g}, {:.6g}, {:.6g}) deg, "
                "another solution than the one nearest the block's start, ({:.6g}, {:.6g}, {:.6g}) mm, ({:.6g}, {:.6g}, {:.6g}) deg "
                "(the orientation passes from one branch of the kinematics to another: split the block)",
                where(b), points.back().q.linear_mm[0], points.back().q.linear_mm[1], points.back().q.linear_mm[2],
                points.back().q.rotary_deg[0], points.back().q.rotary_deg[1], points.back().q.rotary_deg[2], end.linear_mm[0],
                end.linear_mm[1], end.linear_mm[2], end.rotary_deg[0], end.rotary_deg[1], end.rotary_deg[2]));
        points.back().q = end;   // the reader's end, digit for digit: the next block starts there

        for (std::size_t k = 0; k + 1 < points.size(); ++k) {
            NcBlock piece = b;
            piece.tcp = ToolCentrePoint::Off;
            piece.start_mm = points[k].q.linear_mm;
            piece.end_mm = points[k + 1].q.linear_mm;
            piece.start_deg = points[k].q.rotary_deg;
            piece.end_deg = points[k + 1].q.rotary_deg;
            piece.tip_start_mm = tip_at(points[k].u);
            piece.tip_end_mm = tip_at(points[k + 1].u);
            piece.axis_start = vector ? axis_at(points[k].u) : kinematics.forward(points[k].q).axis;
            piece.axis_end = vector ? axis_at(points[k + 1].u) : kinematics.forward(points[k + 1].q).axis;
            piece.feed_time_s = b.feed_time_s * (points[k + 1].u - points[k].u);
            out.blocks.push_back(std::move(piece));
        }
    }
    return out;
}

}  // namespace cutload::app
