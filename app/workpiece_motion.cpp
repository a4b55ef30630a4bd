#include "app/workpiece_motion.hpp"

#include "app/inputs.hpp"
#include "app/predict_run.hpp"
#include "machine/kinematics.hpp"
#include "machine/twist.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <numbers>
#include <stdexcept>

namespace cutload::app {

namespace {

// Where each axis of the chain reads its position in the motion model.
struct AxisSource {
    const std::vector<double>* position = nullptr;
    const std::vector<double>* rate = nullptr;
};

int rotary_index(const std::string& channel) {
    if (channel.size() == 1) {
        const char c = char(std::tolower(static_cast<unsigned char>(channel[0])));
        if (c >= 'a' && c <= 'c') return c - 'a';
    }
    return -1;
}

// The log channel (0..2: a, b, c) a rotary axis of the machine reads.
int rotary_channel(const machine::Machine& machine, const machine::Axis& a) {
    const std::string channel = a.channel.empty() ? std::string(1, char(std::tolower(a.name))) : a.channel;
    const int k = rotary_index(channel);
    if (k < 0)
        throw WorkpieceMotionError(fmt::format("machine {}: rotary axis {} reads channel '{}', which a log cannot "
                                               "hold (a, b or c)",
                                               machine.name, a.name, channel));
    return k;
}

// The one message for a log without a rotary axis's channel, from the ingested motion or from the
// inspect report alike.
void require_rotary(const machine::Machine& machine, const machine::Axis& a, int k, bool present) {
    if (!present)
        throw WorkpieceMotionError(fmt::format("machine {}: rotary axis {} needs column '{}' in the log, which has "
                                               "none",
                                               machine.name, a.name, char('a' + k)));
}

std::vector<AxisSource> axis_sources(const motion_io::MotionModel& m, const machine::Machine& machine) {
    std::vector<AxisSource> out;
    for (const machine::Axis& a : machine.chain) {
        AxisSource s;
        if (!a.rotary()) {
            switch (a.name) {
                case 'X': s = {&m.x_mm, &m.vx_mm_s}; break;
                case 'Y': s = {&m.y_mm, &m.vy_mm_s}; break;
                case 'Z': s = {&m.z_mm, &m.vz_mm_s}; break;
                default:
                    throw WorkpieceMotionError(fmt::format("machine {}: linear axis {} has no channel in a log (x, y, z only)",
                                                           machine.name, a.name));
            }
        } else {
            const int k = rotary_channel(machine, a);
            require_rotary(machine, a, k, m.has_rotary(k));
            s = {&m.rot_deg[std::size_t(k)], &m.rot_vel_deg_s[std::size_t(k)]};
        }
        out.push_back(s);
    }
    return out;
}

double tilt_from_z_rad(const machine::ToolPose& pose) { return lean_from_z_rad(pose.axis()); }

// Angle of the tool frame's x about the cutting frame's z (the tool axis), in degrees.
double frame_turn_deg(const machine::ToolPose& pose, const Eigen::Matrix3d& cutting) {
    const Eigen::Matrix3d R = cutting.transpose() * pose.tool_to_workpiece.R;
    return std::atan2(R(1, 0), R(0, 0)) * 180.0 / std::numbers::pi;
}

constexpr double kDegPerRad = 180.0 / std::numbers::pi;

// Whether the segment from the tip up `axis` for `length_mm` passes within the reach's radius
// (plus the margin) of the stock box: the segment against the box grown by that much on every
// side (a little more than the rounded box: it errs toward "can reach").
bool can_reach(const Eigen::Vector3d& tip_workpiece_mm, const Eigen::Vector3d& axis, double length_mm,
               const ToolReach& reach) {
    const double grow = reach.radius_mm + kReachMarginMm;
    double t0 = 0, t1 = 1;
    for (int k = 0; k < 3; ++k) {
        const double p = tip_workpiece_mm[k] + reach.offset_mm[std::size_t(k)], d = axis[k] * length_mm;
        const double lo = reach.stock_box.min_mm[k] - grow, hi = reach.stock_box.max_mm[k] + grow;
        if (std::abs(d) < 1e-12) {
            if (p < lo || p > hi) return false;
            continue;
        }
        double a = (lo - p) / d, b = (hi - p) / d;
        if (a > b) std::swap(a, b);
        t0 = std::max(t0, a), t1 = std::min(t1, b);
        if (t0 > t1) return false;
    }
    return true;
}

// The tool spans the tool length from its tip, and at least the cutter and holder the spec
// describes (a tool length of 0 is the service's default).
double reach_length_mm(double tool_length_mm, const ToolReach& reach) {
    return std::max({tool_length_mm, reach.length_mm, reach.radius_mm});
}

// The machine's errors may lean the tool by their microradians; more is a definition in the wrong
// units, refused naming the time.
void check_error_tilt(const machine::ToolPose& pose, const machine::ToolPose& nominal, double t_s) {
    const double error_tilt_rad = std::acos(std::clamp(pose.axis().dot(nominal.axis()), -1.0, 1.0));
    if (!(error_tilt_rad <= kErrorTiltLimitRad))
        throw WorkpieceMotionError(fmt::format(
            "at t = {:.4f} s the machine's geometric errors lean the tool {:.4g} deg from its commanded axis, "
            "more than the {:.4g} deg a tool may lean by them (check the errors' units: micrometres per metre)",
            t_s, error_tilt_rad * kDegPerRad, kErrorTiltLimitRad * kDegPerRad));
}

// The axes at sample i and +-h_s along their own rates (joint space), for central differences.
void axes_around(const std::vector<AxisSource>& sources, std::size_t i, double h_s, machine::AxisPositions& q,
                 machine::AxisPositions& q_lo, machine::AxisPositions& q_hi) {
    for (std::size_t k = 0; k < sources.size(); ++k) {
        const double p = (*sources[k].position)[i], v = (*sources[k].rate)[i];
        q.value[k] = p, q_lo.value[k] = p - h_s * v, q_hi.value[k] = p + h_s * v;
    }
}

}  // namespace

double lean_from_z_rad(const Eigen::Vector3d& axis) { return std::atan2(std::hypot(axis.x(), axis.y()), axis.z()); }

double orientation_angle_rad(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
    const double c = ((a.transpose() * b).trace() - 1) / 2;
    return std::acos(std::clamp(c, -1.0, 1.0));
}

Eigen::Matrix3d tool_to_workpiece(const force_model::Rotation3& grid_from_stock) {
    // Row-major G = R^T: G(r, c) = R(c, r).
    Eigen::Matrix3d R;
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) R(c, r) = grid_from_stock.m[std::size_t(3 * r + c)];
    return R;
}

force_model::Rotation3 ToolFrame::grid_from_stock() const {
    force_model::Rotation3 g;
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) g.m[std::size_t(3 * r + c)] = tool_to_workpiece(c, r);
    return g;
}

double off_orientation_rad(const ToolFrame& f, const machine::ToolPose& p, double length_mm, const ToolReach& reach) {
    // A vertical tool may turn about its axis (a C table under it); a tilted one may not.
    const double off = f.tilted ? orientation_angle_rad(f.tool_to_workpiece, p.tool_to_workpiece.R) : tilt_from_z_rad(p);
    if (!(off > kFixedOrientationToleranceRad)) return 0;
    if (!can_reach(p.tip_mm(), p.axis(), length_mm, reach) &&
        !can_reach(p.tip_mm(), f.tool_to_workpiece.col(2), length_mm, reach))
        return 0;
    return off;
}

CuttingOrientationWatch::CuttingOrientationWatch(const machine::Machine& machine, double tool_length_mm,
                                                 const ToolReach& reach)
    : machine_(machine), tool_length_mm_(tool_length_mm), reach_length_mm_(reach_length_mm(tool_length_mm, reach)),
      reach_(reach) {
    // The channels axis_sources() maps the chain to, as MotionState's fields.
    for (const machine::Axis& a : machine.chain) {
        if (a.rotary()) {
            sources_.push_back(3 + rotary_channel(machine, a));
        } else if (a.name >= 'X' && a.name <= 'Z') {
            sources_.push_back(a.name - 'X');
        } else {
            throw WorkpieceMotionError(fmt::format("machine {}: linear axis {} has no channel in a log (x, y, z only)",
                                                   machine.name, a.name));
        }
    }
}

bool CuttingOrientationWatch::see(const machine::AxisPositions& q, double t_s) {
    if (found_) return false;
    if (!seen_any_) first_t_s_ = t_s, seen_any_ = true;
    const machine::ToolPose p = machine::forward(machine_, q, tool_length_mm_, machine::ErrorMode::Nominal);
    if (!can_reach(p.tip_mm(), p.axis(), reach_length_mm_, reach_)) return true;
    found_ = true;
    first_t_s_ = t_s;
    first_ = p.tool_to_workpiece.R;
    lean_rad_ = tilt_from_z_rad(p);
    return false;
}

bool CuttingOrientationWatch::see(const motion_io::MotionState& s) {
    machine::AxisPositions q;
    for (std::size_t k = 0; k < sources_.size(); ++k)
        q.value[k] = sources_[k] < 3 ? s.pos_mm[sources_[k]] : s.rot_deg[sources_[k] - 3];
    return see(q, s.t_s);
}

ToolFrame CuttingOrientationWatch::frame() const {
    ToolFrame f;
    f.checked = true;
    f.t_s = first_t_s_;
    // A tool that never reaches the stock cuts nothing at any orientation: the stock's own frame.
    if (!found_) return f;
    f.lean_deg = lean_rad_ * kDegPerRad;
    f.tilted = lean_rad_ > kFixedOrientationToleranceRad;
    if (f.tilted) f.tool_to_workpiece = first_;
    return f;
}

ToolFrame tool_frame(const motion_io::MotionModel& axes, const machine::Machine& machine, double tool_length_mm,
                     const ToolReach& reach) {
    const std::vector<AxisSource> sources = axis_sources(axes, machine);
    const std::size_t n = axes.size();
    if (n == 0) throw WorkpieceMotionError("the tool's orientation of an empty motion model");
    const double length_mm = reach_length_mm(tool_length_mm, reach);
    const auto positions_at = [&](std::size_t i) {
        machine::AxisPositions q;
        for (std::size_t k = 0; k < sources.size(); ++k) q.value[k] = (*sources[k].position)[i];
        return q;
    };
    const auto pose_at = [&](std::size_t i) {
        return machine::forward(machine, positions_at(i), tool_length_mm, machine::ErrorMode::Nominal);
    };
    // The orientation by the rule the upload applies as it reads the log (CuttingOrientationWatch).
    CuttingOrientationWatch watch(machine, tool_length_mm, reach);
    for (std::size_t i = 0; i < n && watch.see(positions_at(i), axes.t_s[i]); ++i) {
    }
    ToolFrame f = watch.frame();
    if (!watch.found()) return f;
    std::size_t bad = n;
    double bad_off = 0, most_off = 0, most_t = 0;
    // From the log's start: the engine puts the tool at the cutting orientation at every sample, so
    // an approach or index before the first cut must keep that tool clear of the stock too.
    for (std::size_t i = 0; i < n; ++i) {
        const double off = off_orientation_rad(f, pose_at(i), length_mm, reach);
        if (off == 0) continue;
        if (bad == n) bad = i, bad_off = off;
        if (off > most_off) most_off = off, most_t = axes.t_s[i];
    }
    if (bad < n) {
        // The first sample past the tolerance may be microradians where a turn begins: the message
        // also says how far it goes.
        const std::string from = f.tilted ? fmt::format("turns {:.4g} deg from the orientation it cuts at from t = {:.4f} "
                                                        "s (leaning {:.4g} deg from the stock's +Z)",
                                                        bad_off * kDegPerRad, f.t_s, f.lean_deg)
                                          : fmt::format("leans {:.4g} deg from the stock's +Z", bad_off * kDegPerRad);
        throw ToolTurnsInStock(fmt::format(
            "at t = {:.4f} s, where the tool can reach the stock, the tool axis {} (at most {:.4g} deg, at t = "
            "{:.4f} s): a tilted tool is predicted at one fixed orientation wherever it can reach the stock (3+2 "
            "work); a tool that turns there is predicted on the multi-direction stock (docs/five_axis.md, section "
            "3.4)",
            axes.t_s[bad], from, most_off * kDegPerRad, most_t));
    }
    return f;
}

TurningMotion turning_motion(const motion_io::MotionModel& axes, const machine::Machine& machine, double tool_length_mm) {
    const std::vector<AxisSource> sources = axis_sources(axes, machine);
    const std::size_t n = axes.size();
    for (const AxisSource& s : sources)
        if (s.position->size() != n || s.rate->size() != n)
            throw WorkpieceMotionError("a motion model whose axis channels are not as long as its time axis");
    TurningMotion out;
    out.motion = axes;
    out.motion.rot_deg = {};
    out.motion.rot_vel_deg_s = {};
    out.poses.tool_to_stock.resize(n);
    out.poses.omega_tool_rad_s.resize(n);
    constexpr double h_s = 1e-4;   // as workpiece_motion's central difference
    machine::AxisPositions q, q_lo, q_hi;
    for (std::size_t i = 0; i < n; ++i) {
        axes_around(sources, i, h_s, q, q_lo, q_hi);
        const machine::ToolPose pose = machine::forward(machine, q, tool_length_mm);
        const machine::ToolPose nominal = machine::forward(machine, q, tool_length_mm, machine::ErrorMode::Nominal);
        check_error_tilt(pose, nominal, axes.t_s[i]);
        const machine::ToolPose lo = machine::forward(machine, q_lo, tool_length_mm);
        const machine::ToolPose hi = machine::forward(machine, q_hi, tool_length_mm);
        const Eigen::Vector3d v = (hi.tip_mm() - lo.tip_mm()) / (2 * h_s);
        out.motion.x_mm[i] = pose.tip_mm().x(), out.motion.y_mm[i] = pose.tip_mm().y(), out.motion.z_mm[i] = pose.tip_mm().z();
        out.motion.vx_mm_s[i] = v.x(), out.motion.vy_mm_s[i] = v.y(), out.motion.vz_mm_s[i] = v.z();
        const Eigen::Matrix3d& R = pose.tool_to_workpiece.R;
        for (int r = 0; r < 3; ++r)
            for (int c = 0; c < 3; ++c) out.poses.tool_to_stock[i].m[std::size_t(3 * r + c)] = R(r, c);
        // Rows of zero rate give the zero twist: lo and hi are the same pose.
        const Eigen::Vector3d w = machine::interval_twist(lo.tool_to_workpiece, hi.tool_to_workpiece, 2 * h_s).omega_rad_s;
        out.poses.omega_tool_rad_s[i] = {w.x(), w.y(), w.z()};
        out.max_lean_deg = std::max(out.max_lean_deg, tilt_from_z_rad(nominal) * kDegPerRad);
    }
    return out;
}

void turn_forces(std::span<force_model::ForceSample> rows, const Eigen::Matrix3d& tool_to_stock) {
    for (force_model::ForceSample& s : rows) {
        const Eigen::Vector3d f = tool_to_stock * Eigen::Vector3d(s.fx_N, s.fy_N, s.fz_N);
        s.fx_N = float(f.x()), s.fy_N = float(f.y()), s.fz_N = float(f.z());
    }
}

void turn_motion(motion_io::MotionModel& m, const Eigen::Matrix3d& rotation) {
    for (std::size_t i = 0; i < m.size(); ++i) {
        const Eigen::Vector3d p = rotation * Eigen::Vector3d(m.x_mm[i], m.y_mm[i], m.z_mm[i]);
        const Eigen::Vector3d v = rotation * Eigen::Vector3d(m.vx_mm_s[i], m.vy_mm_s[i], m.vz_mm_s[i]);
        m.x_mm[i] = p.x(), m.y_mm[i] = p.y(), m.z_mm[i] = p.z();
        m.vx_mm_s[i] = v.x(), m.vy_mm_s[i] = v.y(), m.vz_mm_s[i] = v.z();
    }
}

motion_io::MotionModel workpiece_motion(const motion_io::MotionModel& axes, const machine::Machine& machine,
                                        double tool_length_mm, const ToolFrame& frame) {
    const std::vector<AxisSource> sources = axis_sources(axes, machine);
    const std::size_t n = axes.size();
    for (const AxisSource& s : sources)
        if (s.position->size() != n || s.rate->size() != n)
            throw WorkpieceMotionError("a motion model whose axis channels are not as long as its time axis");
    // Time, blocks, tools, sessions and spindle carry over; positions, velocities and the spindle
    // angle are overwritten below. The rotary channels are spent on the pose.
    motion_io::MotionModel out = axes;
    out.rot_deg = {};
    out.rot_vel_deg_s = {};

    // The derivative along the axes' rates by a central difference over +-h of time: the chain
    // is smooth, so the error (h^2 times the third derivative) is far below a micrometre per second.
    constexpr double h_s = 1e-4;
    machine::AxisPositions q, q_lo, q_hi;
    double home_turn_deg = 0, last_turn_deg = 0, unwrapped_turn_deg = 0;
    bool turn_known = false;
    for (std::size_t i = 0; i < n; ++i) {
        axes_around(sources, i, h_s, q, q_lo, q_hi);
        // The commanded orientation must be vertical; the machine's errors may lean it by their
        // microradians, which the vertical-tool engine then leaves out (their tip offset is kept).
        const machine::ToolPose pose = machine::forward(machine, q, tool_length_mm);
        const machine::ToolPose nominal = machine::forward(machine, q, tool_length_mm, machine::ErrorMode::Nominal);
        const double tilt_rad = tilt_from_z_rad(nominal);
        if (!frame.checked && !(tilt_rad <= kVerticalToleranceRad)) {
            // The first lean past the tolerance may be a few microradians where a tilt begins: say
            // how far the log goes too, so the message shows what the program does.
            double most_rad = tilt_rad, most_t_s = axes.t_s[i];
            for (std::size_t j = i + 1; j < n; ++j) {
                machine::AxisPositions qj;
                for (std::size_t k = 0; k < sources.size(); ++k) qj.value[k] = (*sources[k].position)[j];
                const double tj = tilt_from_z_rad(machine::forward(machine, qj, tool_length_mm, machine::ErrorMode::Nominal));
                if (tj > most_rad) most_rad = tj, most_t_s = axes.t_s[j];
            }
            throw WorkpieceMotionError(fmt::format(
                "at t = {:.4f} s the tool axis leans {:.4g} deg from the stock's +Z (at most {:.4g} deg, at t = {:.4f} "
                "s): a tilted tool is taken at the fixed orientation tool_frame() finds, or on the multi-direction "
                "stock through turning_motion() (docs/five_axis.md, sections 2.5 and 3.4)",
                axes.t_s[i], tilt_rad * 180.0 / std::numbers::pi, most_rad * 180.0 / std::numbers::pi, most_t_s));
        }
        check_error_tilt(pose, nominal, axes.t_s[i]);
        const machine::ToolPose lo = machine::forward(machine, q_lo, tool_length_mm);
        const machine::ToolPose hi = machine::forward(machine, q_hi, tool_length_mm);
        // In the tool's frame for a fixed tilt (the identity otherwise).
        const Eigen::Matrix3d& cutting = frame.tool_to_workpiece;
        const Eigen::Vector3d tip = cutting.transpose() * pose.tip_mm(),
                              v = cutting.transpose() * (hi.tip_mm() - lo.tip_mm()) / (2 * h_s);
        out.x_mm[i] = tip.x(), out.y_mm[i] = tip.y(), out.z_mm[i] = tip.z();
        out.vx_mm_s[i] = v.x(), out.vy_mm_s[i] = v.y(), out.vz_mm_s[i] = v.z();

        // The cutter's angle against the part: the spindle's, less the tool frame's own turn about
        // the cutting axis since the first sample on that axis (unwrapped), so a machine at rest
        // reads as a three-axis one. A turn about the cutting axis is only defined while the tool
        // stands on it: samples off it (an index in the air, which tool_frame has checked) leave the
        // angle and speed as logged, and the count resumes where the tool is back.
        const bool on_axis = (cutting.col(2) - nominal.axis()).norm() <= kFixedOrientationToleranceRad;
        double turn_rate_deg_s = 0;
        if (on_axis) {
            const double turn = frame_turn_deg(pose, cutting);
            if (!turn_known) {
                home_turn_deg = last_turn_deg = unwrapped_turn_deg = turn;
                turn_known = true;
            } else {
                unwrapped_turn_deg += std::remainder(turn - last_turn_deg, 360.0);
                last_turn_deg = turn;
            }
            turn_rate_deg_s = std::remainder(frame_turn_deg(hi, cutting) - frame_turn_deg(lo, cutting), 360.0) / (2 * h_s);
        }
        out.spindle_angle_deg[i] = axes.spindle_angle_deg[i] - (unwrapped_turn_deg - home_turn_deg);
        // A stopped spindle stays stopped (the engine flags it in material), whatever the table does.
        if (std::abs(axes.spindle_rpm[i]) >= 1) out.spindle_rpm[i] = axes.spindle_rpm[i] - turn_rate_deg_s / 6.0;
    }
    return out;
}

MachineAxesForces::MachineAxesForces(motion_io::MotionModel axes, std::shared_ptr<const machine::Machine> machine)
    : axes_(std::move(axes)), machine_(std::move(machine)) {
    if (axes_.size() == 0) throw WorkpieceMotionError("machine-axis forces of an empty motion model");
    // The same channels workpiece_motion() reads (which has refused a log that lacks one).
    for (const AxisSource& a : axis_sources(axes_, *machine_)) {
        const std::vector<double>* p = a.position;
        source_.push_back(p == &axes_.x_mm ? 0 : p == &axes_.y_mm ? 1 : p == &axes_.z_mm ? 2
                          : p == &axes_.rot_deg[0] ? 3 : p == &axes_.rot_deg[1] ? 4 : 5);
    }
    // Until the engine says otherwise, the first session (the whole model when it has one).
    const std::vector<std::size_t>& starts = axes_.session_start;
    const auto later = std::upper_bound(starts.begin(), starts.end(), std::size_t(0));
    end_ = later == starts.end() ? axes_.size() : *later;
    several_sessions_ = end_ < axes_.size();
}

void MachineAxesForces::begin_session(std::size_t begin, std::size_t end, std::size_t first_row) {
    // One of the model's sessions: it starts at 0 or at a listed start, and ends at the next.
    const std::vector<std::size_t>& starts = axes_.session_start;
    const auto later = std::upper_bound(starts.begin(), starts.end(), begin);
    const std::size_t session_end = later == starts.end() ? axes_.size() : *later;
    const bool listed = begin == 0 || std::binary_search(starts.begin(), starts.end(), begin);
    if (!listed || end != session_end || begin >= end)
        throw std::invalid_argument(fmt::format("machine-axis forces: samples [{}, {}) are not a session of the motion "
                                                "model ({} samples, {} session starts)",
                                                begin, end, axes_.size(), starts.size()));
    if (!starts_.empty() && first_row < starts_.back().first_row)
        throw std::invalid_argument(fmt::format("machine-axis forces: a session said to begin at row {}, before the "
                                                "previous one's row {}",
                                                first_row, starts_.back().first_row));
    starts_.push_back({first_row, begin, end});
}

MachineAxesForces::Place MachineAxesForces::locate(double t_s) {
    const std::vector<double>& t = axes_.t_s;
    const std::size_t b = begin_, e = end_;
    // Within one session the rows come in time order: on from the cursor; a row before it (not
    // written so by the engine) is looked up.
    const double clamped = std::clamp(t_s, t[b], t[e - 1]);
    std::size_t i = std::max(index_, b);
    if (clamped < t[i]) {
        const auto it = std::upper_bound(t.begin() + std::ptrdiff_t(b), t.begin() + std::ptrdiff_t(e), clamped);
        i = std::size_t(it - t.begin()) - 1;
    }
    while (i + 2 < e && t[i + 1] <= clamped) ++i;
    index_ = i;
    return {i, i + 1 < e, clamped};
}

void MachineAxesForces::apply(std::span<force_model::ForceSample> rows) {
    if (several_sessions_ && starts_.empty() && !rows.empty())
        throw std::logic_error("machine-axis forces of a motion model of several sessions need the engine's word on "
                               "where each session's rows begin (PredictOptions::session_begins)");
    machine::AxisPositions q;
    for (force_model::ForceSample& row : rows) {
        // The session this row is of: the last one the engine began at or before its row.
        while (next_start_ < starts_.size() && starts_[next_start_].first_row <= rows_seen_) {
            begin_ = starts_[next_start_].begin, end_ = starts_[next_start_].end, index_ = begin_;
            ++next_start_;
        }
        ++rows_seen_;
        const Place at = locate(row.t_s);
        motion_io::MotionState st;
        if (at.interval) {
            st = motion_io::sample_between(axes_, at.index, at.t_s);
        } else {
            st.pos_mm[0] = axes_.x_mm[at.index], st.pos_mm[1] = axes_.y_mm[at.index], st.pos_mm[2] = axes_.z_mm[at.index];
            for (std::size_t k = 0; k < 3; ++k)
                if (axes_.has_rotary(int(k))) st.rot_deg[k] = axes_.rot_deg[k][at.index];
        }
        for (std::size_t k = 0; k < source_.size(); ++k)
            q.value[k] = source_[k] < 3 ? st.pos_mm[source_[k]] : st.rot_deg[source_[k] - 3];
        // The axis turns with every rotary axis of the chain (a head's too), errors included, as the
        // engine's motion was made (workpiece_motion); it does not depend on the tool's length. One
        // walk of the chain gives it and R_bed (the workpiece-side part of the same product).
        const machine::ToolAndBed frames = machine::forward_with_bed(*machine_, q, 0.0);
        const Eigen::Vector3d axis = frames.tool.axis();
        row.tool_axis_x = float(axis.x()), row.tool_axis_y = float(axis.y()), row.tool_axis_z = float(axis.z());
        const Eigen::Matrix3d& R = frames.bed_to_workpiece.R;
        if (R == Eigen::Matrix3d::Identity()) {
            row.fx_machine_N = row.fx_N, row.fy_machine_N = row.fy_N, row.fz_machine_N = row.fz_N;
            continue;
        }
        // R turns machine axes into workpiece axes; its transpose turns them back.
        const Eigen::Vector3d f_m = R.transpose() * Eigen::Vector3d(row.fx_N, row.fy_N, row.fz_N);
        row.fx_machine_N = float(f_m.x()), row.fy_machine_N = float(f_m.y()), row.fz_machine_N = float(f_m.z());
    }
}

std::string machine_rotary_axes(const machine::Machine& machine) {
    std::string out;
    for (const char letter : {'A', 'B', 'C'})
        for (const machine::Axis& a : machine.chain)
            if (a.rotary() && a.name == letter) out += letter;
    return out;
}

namespace {

// Calls f(axis, letter, channel) for each rotary axis of the machine named A, B or C: the index of
// its letter (what the NC reader's angles are indexed by) and of the log channel it reads.
template <typename F>
void for_each_rotary(const machine::Machine& machine, F&& f) {
    for (const machine::Axis& a : machine.chain) {
        const int letter = rotary_index(std::string(1, a.name));
        if (a.rotary() && letter >= 0) f(a, std::size_t(letter), std::size_t(rotary_channel(machine, a)));
    }
}

}  // namespace

std::array<double, 3> rotary_start_by_letter(const motion_io::MotionModel& log, const machine::Machine& machine) {
    std::array<double, 3> out{};
    for_each_rotary(machine, [&](const machine::Axis& a, std::size_t l, std::size_t k) {
        require_rotary(machine, a, int(k), log.has_rotary(int(k)));
        out[l] = log.rot_deg[k].front();
    });
    return out;
}

void program_axes_as_log(motion_io::MotionModel& axes, const motion_io::NcProgram& program,
                         const machine::Machine& machine) {
    std::array<std::vector<double>, 3> rot, vel;
    for_each_rotary(machine, [&](const machine::Axis&, std::size_t l, std::size_t k) {
        if (axes.has_rotary(int(l))) {
            rot[k] = axes.rot_deg[l];
            vel[k] = axes.rot_vel_deg_s[l];
        } else {
            // Not in the program: every block holds it at its start (NcReadOptions::start_deg).
            rot[k].assign(axes.size(), program.blocks.empty() ? 0.0 : program.blocks.front().start_deg[l]);
            vel[k].assign(axes.size(), 0.0);
        }
    });
    axes.rot_deg = std::move(rot);
    axes.rot_vel_deg_s = std::move(vel);
}

namespace {

// The machine's axes at fraction u of a program block: X/Y/Z on its path, the rotary axes linear.
machine::AxisPositions block_axes(const machine::Machine& machine, const motion_io::NcBlock& b, double u) {
    double p[3], tangent[3];
    motion_io::block_point(b, u, p, tangent);
    machine::AxisPositions q;
    for (std::size_t k = 0; k < machine.chain.size(); ++k) {
        const machine::Axis& a = machine.chain[k];
        if (a.rotary()) {
            const auto r = std::size_t(a.name - 'A');
            q.value[k] = b.start_deg[r] + u * (b.end_deg[r] - b.start_deg[r]);
        } else {
            q.value[k] = p[a.name - 'X'];
        }
    }
    return q;
}

// workpiece_program and turning_workpiece_program: the tip's path, with the orientation held to
// the log's rule (a checked frame and the reach), to the vertical (neither), or free (any_orientation).
motion_io::NcProgram tip_program(const motion_io::NcProgram& program, const machine::Machine& machine,
                                 double tool_length_mm, double rapid_mm_min, const PieceLimits& limits,
                                 const ToolFrame& frame, const std::optional<ToolReach>& reach, bool any_orientation) {
    using motion_io::NcBlock;
    using motion_io::NcMotion;
    const bool checked = !any_orientation && frame.checked && reach.has_value();
    const double length_mm = reach ? reach_length_mm(tool_length_mm, *reach) : tool_length_mm;
    auto tip = [&](const NcBlock& b, double u) {
        const machine::AxisPositions q = block_axes(machine, b, u);
        if (any_orientation) return Eigen::Vector3d(machine::forward(machine, q, tool_length_mm).tip_mm());
        const machine::ToolPose nominal = machine::forward(machine, q, tool_length_mm, machine::ErrorMode::Nominal);
        if (checked) {
            // The log's rule (tool_frame): the commanded tool keeps the orientation the log cuts at
            // wherever it can reach the stock.
            if (const double off = off_orientation_rad(frame, nominal, length_mm, *reach); off > 0)
                throw motion_io::NcProgramError(fmt::format(
                    "{}:{}: block {}: where the tool can reach the stock its axis {} {:.4g} deg from the orientation "
                    "the log cuts at (leaning {:.4g} deg from the stock's +Z): the log holds the tool at one "
                    "orientation there (3+2 work), so the program must too; a log whose tool turns where it cuts is "
                    "compared with a program that turns it (docs/five_axis.md, section 3.4)",
                    program.file, b.line, b.name, frame.tilted ? "turns" : "leans", off * 180.0 / std::numbers::pi,
                    frame.lean_deg));
        } else if (const double tilt_rad = tilt_from_z_rad(nominal); !(tilt_rad <= kVerticalToleranceRad)) {
            throw motion_io::NcProgramError(fmt::format(
                "{}:{}: block {}: the tool axis leans {:.4g} deg from the stock's +Z, and the program is read "
                "without the log's orientations, which a tilted tool's commanded path needs (docs/five_axis.md, "
                "section 2.5)",
                program.file, b.line, b.name, tilt_rad * 180.0 / std::numbers::pi));
        }
        return Eigen::Vector3d(machine::forward(machine, q, tool_length_mm).tip_mm());
    };
    // The rule depends on where the tool is, so a block is checked along its path, not only where
    // its pieces end: a straight rapid at another orientation may cross the part with both ends
    // clear. Steps no longer than the widest radius (the reach test grows the box by more), and
    // half a degree of any rotary axis; at most 4096 a block.
    auto check_along = [&](const NcBlock& b) {
        if (!checked || !(motion_io::block_moves(b) || motion_io::block_turns(b))) return;
        double travel_mm = 0, turn_deg = 0;
        for (std::size_t k = 0; k < 3; ++k) {
            travel_mm = std::hypot(travel_mm, b.end_mm[k] - b.start_mm[k]);
            turn_deg = std::max(turn_deg, std::abs(b.end_deg[k] - b.start_deg[k]));
        }
        if (b.motion == NcMotion::ArcCw || b.motion == NcMotion::ArcCcw)
            travel_mm = std::max(travel_mm, std::abs(b.sweep_rad) * std::hypot(b.start_mm[std::size_t(b.plane_axes[0])] - b.center_mm[std::size_t(b.plane_axes[0])],
                                                                                 b.start_mm[std::size_t(b.plane_axes[1])] - b.center_mm[std::size_t(b.plane_axes[1])]));
        const double step_mm = std::max(1.0, reach->radius_mm);
        const double steps = std::clamp(std::max(std::ceil(travel_mm / step_mm), std::ceil(turn_deg / 0.5)), 1.0, 4096.0);
        for (int k = 1; k < int(steps); ++k) tip(b, double(k) / steps);
    };
    auto set_ends = [](NcBlock& piece, const Eigen::Vector3d& from, const Eigen::Vector3d& to) {
        for (int k = 0; k < 3; ++k) piece.start_mm[std::size_t(k)] = from[k], piece.end_mm[std::size_t(k)] = to[k];
        piece.start_deg = piece.end_deg = {};
    };

    motion_io::NcProgram out = program;
    out.blocks.clear();
    out.rotary_axes.clear();
    // The pieces a block may have: its own limit, and what the program's leaves.
    auto room = [&](double pieces) {
        return pieces <= double(limits.per_block) && double(out.blocks.size()) + pieces <= double(limits.total);
    };
    auto too_many = [&](const NcBlock& b, double pieces, double u_reached) {
        const std::string where = u_reached > 0 ? fmt::format(", passed {:.3g} % into the block", 100 * u_reached) : "";
        if (pieces <= double(limits.per_block))
            return motion_io::NcProgramError(fmt::format(
                "{}:{}: block {}: the program's tip path needs more than {} pieces of {} um in all{} (split the program)",
                program.file, b.line, b.name, limits.total, kProgramChordTolMm * 1e3, where));
        return motion_io::NcProgramError(fmt::format(
            "{}:{}: block {}: its tip path needs more than {} pieces of {} um{} (turn the rotary axes less in one block)",
            program.file, b.line, b.name, limits.per_block, kProgramChordTolMm * 1e3, where));
    };
    for (const NcBlock& b : program.blocks) {
        check_along(b);
        const bool arc = b.motion == NcMotion::ArcCw || b.motion == NcMotion::ArcCcw;
        if (!motion_io::block_moves(b) || !(arc || motion_io::block_turns(b))) {
            // At rest, or a line with the rotary axes still: the linear axes move the tip rigidly,
            // so the line stays a line at the same speed.
            if (!room(1)) throw too_many(b, 1, 0);
            NcBlock piece = b;
            set_ends(piece, tip(b, 0), tip(b, 1));
            out.blocks.push_back(std::move(piece));
            continue;
        }
        // At least one piece per quarter turn of any rotary axis or of the arc, so a whole turn
        // (whose ends meet) is never one chord; then bisection to the tolerance.
        double turn_deg = 0;
        for (std::size_t r = 0; r < 3; ++r) turn_deg = std::max(turn_deg, std::abs(b.end_deg[r] - b.start_deg[r]));
        if (arc) turn_deg = std::max(turn_deg, std::abs(b.sweep_rad) * 180.0 / std::numbers::pi);
        const double quarter_turns = std::max(1.0, std::ceil(turn_deg / 90.0));
        // Refused before a single pose is computed when the quarter turns alone are too many.
        if (!room(quarter_turns)) throw too_many(b, quarter_turns, 0);
        const auto initial = std::size_t(quarter_turns);
        std::vector<double> cuts{0.0};
        std::vector<Eigen::Vector3d> tips{tip(b, 0)};
        // Depth-first bisection of [u0, u1] (its start already in `cuts`). The pieces are counted
        // as they are made, so a block that needs too many stops where it passes the limit, before
        // it has taken their memory.
        auto refine = [&](auto&& self, double u0, double u1, const Eigen::Vector3d& p0, const Eigen::Vector3d& p1, int depth) -> void {
            const double um = 0.5 * (u0 + u1);
            const Eigen::Vector3d pm = tip(b, um);
            if (depth < 16 && (pm - 0.5 * (p0 + p1)).norm() > kProgramChordTolMm) {
                self(self, u0, um, p0, pm, depth + 1);
                self(self, um, u1, pm, p1, depth + 1);
                return;
            }
            if (!room(double(cuts.size()))) throw too_many(b, double(cuts.size()), u1);   // this piece would pass
            cuts.push_back(u1);
            tips.push_back(p1);
        };
        for (std::size_t k = 0; k < initial; ++k) {
            const double u0 = double(k) / double(initial), u1 = double(k + 1) / double(initial);
            refine(refine, u0, u1, tips.back(), tip(b, u1), 0);
        }
        const double block_s = motion_io::block_time_s(b, rapid_mm_min);
        // The block's mean tip speed (the tip's speed changes along a block that turns).
        double path_mm = 0;
        for (std::size_t k = 0; k + 1 < tips.size(); ++k) path_mm += (tips[k + 1] - tips[k]).norm();
        const double mean_feed_mm_min = block_s > 0 ? path_mm / block_s * 60.0 : 0.0;
        for (std::size_t k = 0; k + 1 < cuts.size(); ++k) {
            NcBlock piece = b;
            piece.motion = b.motion == NcMotion::Rapid ? NcMotion::Rapid : NcMotion::Linear;
            set_ends(piece, tips[k], tips[k + 1]);
            piece.feed_time_s = block_s * (cuts[k + 1] - cuts[k]);
            const double length_mm = (tips[k + 1] - tips[k]).norm();
            if (!(length_mm > 0) && piece.feed_time_s > 0) {
                // The axes turn about a tip that stays put: the tip path holds it there for the
                // piece's time (a piece that neither moves nor turns would be timed as none), so
                // the two programs keep the same block times.
                piece.motion = NcMotion::Dwell;
                piece.dwell_s = piece.feed_time_s;
            }
            // A turning tool's program: the block's mean tip speed, the one feed the comparison
            // reads. Otherwise each piece's own speed, which a feed override rescales.
            if (b.motion != NcMotion::Rapid && piece.feed_time_s > 0)
                piece.feed_mm_min = any_orientation ? mean_feed_mm_min : length_mm / piece.feed_time_s * 60.0;
            out.blocks.push_back(std::move(piece));
        }
    }
    return out;
}

}  // namespace

motion_io::NcProgram workpiece_program(const motion_io::NcProgram& program, const machine::Machine& machine,
                                       double tool_length_mm, double rapid_mm_min, const PieceLimits& limits,
                                       const ToolFrame& frame, const std::optional<ToolReach>& reach) {
    return tip_program(program, machine, tool_length_mm, rapid_mm_min, limits, frame, reach, false);
}

motion_io::NcProgram turning_workpiece_program(const motion_io::NcProgram& program, const machine::Machine& machine,
                                               double tool_length_mm, double rapid_mm_min, const PieceLimits& limits) {
    return tip_program(program, machine, tool_length_mm, rapid_mm_min, limits, {}, std::nullopt, true);
}

std::shared_ptr<const machine::Machine> load_machine_definition(const MachineFiles& files) {
    auto m = std::make_shared<machine::Machine>();
    try {
        *m = machine::load_machine(files.path, files.shown_as);
    } catch (const std::exception& e) {
        throw InputError("machine", e.what());
    }
    if (!files.errors_path.empty()) {
        try {
            machine::load_errors(*m, files.errors_path, files.errors_shown_as);
        } catch (const std::exception& e) {
            throw InputError("machine_errors", e.what());
        }
    }
    return m;
}

std::shared_ptr<const machine::Machine> load_machine_definition(const std::string& path, const std::string& errors_path) {
    return load_machine_definition(MachineFiles{path, errors_path, "", ""});
}

void check_log_axes(const machine::Machine& machine, const std::string& log_rotary_axes) {
    try {
        for (const machine::Axis& a : machine.chain) {
            if (!a.rotary()) continue;
            const int k = rotary_channel(machine, a);
            require_rotary(machine, a, k, log_rotary_axes.find(char('a' + k)) != std::string::npos);
        }
    } catch (const WorkpieceMotionError& e) {
        throw InputError("machine", e.what());
    }
}

}  // namespace cutload::app
