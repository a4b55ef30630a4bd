#include "motion_io/synth.hpp"

#include "textio/csv.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <iterator>
#include <numbers>
#include <optional>
#include <stdexcept>

namespace cutload::motion_io {
namespace {

// splitmix64 and Box-Muller: the same numbers on every platform, unlike <random>'s distributions.
class Rng {
public:
    explicit Rng(std::uint64_t seed) : s_(seed) {}
    double uniform() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }
    double normal() {
        const double u1 = std::max(uniform(), 1e-300), u2 = uniform();
        return std::sqrt(-2 * std::log(u1)) * std::cos(6.283185307179586 * u2);
    }

private:
    std::uint64_t next() {
        std::uint64_t z = (s_ += 0x9E3779B97F4A7C15ull);
        z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
        z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
        return z ^ (z >> 31);
    }
    std::uint64_t s_;
};

// The machine's axes: X, Y, Z (mm), then A, B, C (deg). Each is interpolated, smoothed and lagged
// on its own, as each servo does; a three-axis run leaves the rotary ones at 0 and unwritten.
constexpr int kAxes = 6;

class MovingAverage {
public:
    MovingAverage(int n, const double start[kAxes]) : ring_(static_cast<std::size_t>(std::max(n, 1))) {
        for (auto& r : ring_) std::copy(start, start + kAxes, r.begin());
        for (int a = 0; a < kAxes; ++a) sum_[a] = start[a] * static_cast<double>(ring_.size());
    }
    void push(const double in[kAxes], double out[kAxes]) {
        auto& slot = ring_[i_];
        for (int a = 0; a < kAxes; ++a) {
            sum_[a] += in[a] - slot[a];
            slot[a] = in[a];
            out[a] = sum_[a] / static_cast<double>(ring_.size());
        }
        i_ = (i_ + 1) % ring_.size();
    }

private:
    std::vector<std::array<double, kAxes>> ring_;
    std::size_t i_ = 0;
    double sum_[kAxes] = {0, 0, 0, 0, 0, 0};
};

// One piece of the machine's work: a path (line or arc) at a speed, or a pause in place.
struct Segment {
    enum class Kind { Line, Arc, Pause } kind = Kind::Line;
    std::string name;
    int tool = -1;
    bool rapid = false;
    double speed_mm_s = 1;      // a pause runs at 1 "mm"/s over pause_s "mm": the path arithmetic times it
    double spindle_rpm = 0;     // target (NC programs)
    double from[kAxes] = {0, 0, 0, 0, 0, 0}, to[kAxes] = {0, 0, 0, 0, 0, 0};   // X Y Z mm, A B C deg
    double length = 0;          // mm (degrees counted as mm when rotary axes turn), or s for a pause
    double time_s = 0;          // > 0: the block's own time (G93, or a rotary feed rule) sets the speed
    NcBlock arc;                // Kind::Arc
    double v_in = 0, v_out = 0, v_max = 0;   // planned path speeds, mm/s (NC programs with max_accel)
};

struct RunSetup {
    double start[kAxes] = {0, 0, 0, 0, 0, 0};   // X Y Z mm, A B C deg
    std::string rotary_axes;    // columns to write ("ac"): the rotary axes the program names
    MachineModel machine;
    double settle_s = 0;
    bool nc = false;            // spindle follows the segments (else the first demo's ramp)
};

// The machine, advanced one CNC period at a time.
class Machine {
public:
    Machine(const RunSetup& run, const std::vector<Segment>& segs)
        : run_(run), m_(run.machine), segs_(segs), ma1_(m_.accdec_ticks[0], run.start), ma2_(m_.accdec_ticks[1], run.start) {
        std::copy(run.start, run.start + kAxes, cmd_);
        std::copy(run.start, run.start + kAxes, act_);
        std::copy(run.start, run.start + kAxes, prev_act_);
        planned_ = run.nc && m_.max_accel_mm_s2 > 0;
        if (segs_.empty()) program_done_ = true;
        else speed_mm_s_ = segs_[0].speed_mm_s;
    }

    // Advances by one CNC period; the latched state is what a read sees until the next tick.
    void tick() {
        const double T = m_.cnc_period_s;
        ++ticks_;
        if (planned_) interpolate_planned(T);
        else interpolate(T);
        double f1[kAxes], f2[kAxes];
        ma1_.push(cmd_, f1);
        ma2_.push(f1, f2);
        const double k = 1.0 - std::exp(-T / m_.servo_time_constant_s);
        std::copy(act_, act_ + kAxes, prev_act_);
        for (int a = 0; a < kAxes; ++a) act_[a] += (f2[a] - act_[a]) * k;
        if (run_.nc && !segs_.empty()) {
            const double target = segs_[std::min(seg_, segs_.size() - 1)].spindle_rpm, step = m_.spindle_accel_rpm_s * T;
            rpm_ += std::clamp(target - rpm_, -step, step);
        }
        if (program_done_) settle_ticks_++;
    }

    double time_s() const { return static_cast<double>(ticks_) * m_.cnc_period_s; }
    bool finished() const { return program_done_ && settle_ticks_ * m_.cnc_period_s >= run_.settle_s; }
    const double* actual() const { return act_; }   // X Y Z mm, A B C deg
    // As a FANUC shows the actual feed: degrees of a turning axis counted as mm.
    double actual_feed_mm_min() const {
        double d2 = 0;
        for (int a = 0; a < kAxes; ++a) d2 += (act_[a] - prev_act_[a]) * (act_[a] - prev_act_[a]);
        return std::sqrt(d2) / m_.cnc_period_s * 60.0;
    }
    double spindle_rpm() const {
        if (run_.nc) return rpm_;
        return m_.spindle_ramp_s > 0 ? m_.spindle_rpm * std::min(1.0, time_s() / m_.spindle_ramp_s) : m_.spindle_rpm;
    }
    const std::string& block_name() const {
        static const std::string none;
        return segs_.empty() ? none : segs_[std::min(seg_, segs_.size() - 1)].name;
    }
    int tool() const { return segs_.empty() ? -1 : segs_[std::min(seg_, segs_.size() - 1)].tool; }

private:
    void place(const Segment& g, double s) {
        if (g.kind == Segment::Kind::Pause) return;
        if (g.kind == Segment::Kind::Arc) {
            double tangent[3];
            block_point(g.arc, g.length > 0 ? s / g.length : 1.0, cmd_, tangent);
            return;
        }
        // Joint space: every axis, linear or rotary, runs linearly along the segment.
        for (int a = 0; a < kAxes; ++a) cmd_[a] = g.from[a] + (g.to[a] - g.from[a]) * s / g.length;
    }
    void arrive(const Segment& g) {
        if (g.kind != Segment::Kind::Pause) std::copy(g.to, g.to + kAxes, cmd_);
    }

    // Continuous-path interpolation at the programmed speed: the distance left over at a block
    // end carries into the next (the first demo's machine).
    void interpolate(double T) {
        if (program_done_) return;
        double travel = speed_mm_s_ * T;
        while (!program_done_) {
            const Segment& g = segs_[seg_];
            const double left = g.length - seg_s_;
            if (travel < left) {
                seg_s_ += travel;
                place(g, seg_s_);
                return;
            }
            const double used_time = left / speed_mm_s_;
            arrive(g);
            if (seg_ + 1 >= segs_.size()) {
                program_done_ = true;
                return;
            }
            const double time_left = travel / speed_mm_s_ - used_time;
            ++seg_;
            seg_s_ = 0;
            speed_mm_s_ = segs_[seg_].speed_mm_s;
            travel = time_left * speed_mm_s_;
        }
    }

    // Acceleration-limited interpolation: the path speed follows the planned profile (at most
    // max_accel up, and down in time for the next junction's speed).
    void interpolate_planned(double T) {
        const double acc = m_.max_accel_mm_s2;
        double t_left = T;
        while (!program_done_ && t_left > 1e-12) {
            const Segment& g = segs_[seg_];
            if (g.kind == Segment::Kind::Pause) {
                const double rest = g.length - seg_s_;
                if (t_left < rest) {
                    seg_s_ += t_left;
                    return;
                }
                t_left -= rest;
                v_ = 0;
                next();
                continue;
            }
            const double L = g.length;
            const double brake = std::sqrt(g.v_out * g.v_out + 2 * acc * std::max(0.0, L - seg_s_));
            const double v_new = std::min({v_ + acc * t_left, g.v_max, brake});
            const double avg = 0.5 * (v_ + v_new);
            // Never stall short of a stop: the distance from rest covered in the time left.
            const double ds = std::max(avg * t_left, std::min(L - seg_s_, 0.5 * acc * t_left * t_left));
            if (seg_s_ + ds >= L - 1e-12) {
                const double used = std::min(t_left, avg > 1e-9 ? (L - seg_s_) / avg : t_left);
                arrive(g);
                t_left -= used;
                v_ = std::min(v_new, g.v_out);
                next();
                continue;
            }
            seg_s_ += ds;
            v_ = v_new;
            place(g, seg_s_);
            return;
        }
    }

    void next() {
        if (seg_ + 1 >= segs_.size()) {
            program_done_ = true;
            return;
        }
        ++seg_;
        seg_s_ = 0;
    }

    const RunSetup& run_;
    const MachineModel& m_;
    const std::vector<Segment>& segs_;
    MovingAverage ma1_, ma2_;
    double cmd_[kAxes], act_[kAxes], prev_act_[kAxes];
    double seg_s_ = 0, speed_mm_s_ = 1, v_ = 0, rpm_ = 0;
    std::size_t seg_ = 0;
    std::size_t ticks_ = 0;
    std::size_t settle_ticks_ = 0;
    bool program_done_ = false, planned_ = false;
};

double quantise(double v, double step) { return step > 0 ? std::round(v / step) * step : v; }

double distance3(const double a[3], const double b[3]) {
    return std::sqrt((b[0] - a[0]) * (b[0] - a[0]) + (b[1] - a[1]) * (b[1] - a[1]) + (b[2] - a[2]) * (b[2] - a[2]));
}

// The joint-space length: degrees counted as mm (FANUC's combined feed). With the rotary axes at
// rest it is distance3, bit for bit (the extra terms add exact zeros).
double joint_distance(const double a[kAxes], const double b[kAxes]) {
    double d2 = (b[0] - a[0]) * (b[0] - a[0]) + (b[1] - a[1]) * (b[1] - a[1]) + (b[2] - a[2]) * (b[2] - a[2]);
    for (int k = 3; k < kAxes; ++k) d2 += (b[k] - a[k]) * (b[k] - a[k]);
    return std::sqrt(d2);
}

std::vector<Segment> segments_of(const DryRunSpec& spec) {
    std::vector<Segment> out;
    double from[3];
    std::copy(spec.start_mm, spec.start_mm + 3, from);
    for (const ProgramBlock& b : spec.program) {
        Segment g;
        g.name = b.name;
        g.rapid = b.rapid;
        const double f = b.rapid ? spec.machine.rapid_mm_min : b.feed_mm_min;
        if (!(f > 0)) throw std::invalid_argument(fmt::format("block {}: feed must be > 0", b.name));
        g.speed_mm_s = f / 60.0;
        std::copy(from, from + 3, g.from);
        std::copy(b.target_mm, b.target_mm + 3, g.to);
        g.length = distance3(g.from, g.to);
        std::copy(b.target_mm, b.target_mm + 3, from);
        out.push_back(g);
    }
    return out;
}

// The unit tangent at the start (u = 0) or end (u = 1) of a path segment.
void tangent_at(const Segment& g, double u, double t[3]) {
    if (g.kind == Segment::Kind::Arc) {
        double p[3];
        block_point(g.arc, u, p, t);
        return;
    }
    for (int a = 0; a < kAxes; ++a) t[a] = g.length > 0 ? (g.to[a] - g.from[a]) / g.length : 0.0;
}

// Junction speeds: zero at pauses, the ends and around rapids (in-position check); at a corner
// the speed at which no axis's velocity jumps by more than the allowed step; then limited so
// that max_accel can reach each from its neighbours.
void plan(std::vector<Segment>& segs, const MachineModel& m) {
    const double acc = m.max_accel_mm_s2, step = m.corner_speed_step_mm_min / 60.0;
    auto path = [](const Segment& g) { return g.kind != Segment::Kind::Pause; };
    for (Segment& g : segs) {
        g.v_max = path(g) ? g.speed_mm_s : 0.0;
        if (g.kind == Segment::Kind::Arc) {
            const int a = g.arc.plane_axes[0], c = g.arc.plane_axes[1];
            const double r = std::hypot(g.arc.start_mm[a] - g.arc.center_mm[a], g.arc.start_mm[c] - g.arc.center_mm[c]);
            g.v_max = std::min(g.v_max, std::sqrt(acc * r));
        }
        g.v_in = g.v_out = 0;
    }
    for (std::size_t k = 0; k + 1 < segs.size(); ++k) {
        Segment &a = segs[k], &b = segs[k + 1];
        if (!path(a) || !path(b) || a.rapid || b.rapid) continue;
        double ta[kAxes] = {0, 0, 0, 0, 0, 0}, tb[kAxes] = {0, 0, 0, 0, 0, 0};
        tangent_at(a, 1.0, ta);
        tangent_at(b, 0.0, tb);
        double jump = 0;
        for (int ax = 0; ax < kAxes; ++ax) jump = std::max(jump, std::abs(tb[ax] - ta[ax]));
        const double v = std::min({a.v_max, b.v_max, jump > 1e-12 ? step / jump : a.v_max});
        a.v_out = b.v_in = v;
    }
    for (std::size_t k = segs.size(); k-- > 0;) {
        Segment& g = segs[k];
        if (!path(g)) continue;
        g.v_in = std::min(g.v_in, std::sqrt(g.v_out * g.v_out + 2 * acc * g.length));
        if (k > 0) segs[k - 1].v_out = std::min(segs[k - 1].v_out, g.v_in);
    }
    for (std::size_t k = 0; k < segs.size(); ++k) {
        Segment& g = segs[k];
        if (!path(g)) continue;
        g.v_out = std::min(g.v_out, std::sqrt(g.v_in * g.v_in + 2 * acc * g.length));
        if (k + 1 < segs.size()) segs[k + 1].v_in = std::min(segs[k + 1].v_in, g.v_out);
    }
}

std::vector<Segment> segments_of(const NcDryRunSpec& spec) {
    std::vector<Segment> out;
    double at[kAxes];
    std::copy(spec.start_mm, spec.start_mm + 3, at);
    std::copy(spec.start_deg, spec.start_deg + 3, at + 3);
    int tool = -1;
    auto add = [&](Segment g) {
        g.tool = tool;
        if (g.kind != Segment::Kind::Pause) {
            std::copy(at, at + kAxes, g.from);
            if (g.kind == Segment::Kind::Line) g.length = joint_distance(g.from, g.to);
            if (g.length < 1e-9) return;
            if (g.time_s > 0) g.speed_mm_s = g.length / g.time_s;
            std::copy(g.to, g.to + kAxes, at);
        } else if (!(g.length > 0)) {
            return;
        }
        out.push_back(std::move(g));
    };
    auto rapid_to = [&](const NcBlock& b, const double to[3], double rpm) {
        Segment g;
        g.name = b.name;
        g.rapid = true;
        g.speed_mm_s = spec.machine.rapid_mm_min / 60.0;
        g.spindle_rpm = rpm;
        std::copy(to, to + 3, g.to);
        std::copy(at + 3, at + kAxes, g.to + 3);   // the tool change leaves the rotary axes where they are
        add(g);
    };
    for (const NcBlock& b : spec.program.blocks) {
        if (b.tool_change) {
            // The control's tool-change cycle: spindle stop, up, across, change.
            const double* tc = spec.tool_change.position_mm;
            const double up[3] = {at[0], at[1], tc[2]};
            rapid_to(b, up, 0);
            rapid_to(b, tc, 0);
            Segment pause;
            pause.kind = Segment::Kind::Pause;
            pause.name = b.name;
            pause.length = spec.tool_change.time_s;
            add(pause);
            tool = b.tool;
        }
        Segment g;
        g.name = b.name;
        g.spindle_rpm = b.spindle_rpm;
        switch (b.motion) {
            case NcMotion::Rapid:
            case NcMotion::Linear:
                g.rapid = b.motion == NcMotion::Rapid;
                g.speed_mm_s = (g.rapid ? spec.machine.rapid_mm_min : b.feed_mm_min) / 60.0;
                std::copy(b.end_mm.begin(), b.end_mm.end(), g.to);
                std::copy(b.end_deg.begin(), b.end_deg.end(), g.to + 3);
                // G93, or a feed move that turns a rotary axis: the block's own time (by the
                // program's rotary feed rule) over its joint-space length.
                if (!g.rapid && (b.feed_time_s > 0 || block_turns(b))) g.time_s = block_time_s(b, spec.machine.rapid_mm_min);
                add(g);
                break;
            case NcMotion::ArcCw:
            case NcMotion::ArcCcw:
                if (distance3(at, b.start_mm.data()) > 1e-6)
                    throw std::invalid_argument(fmt::format("{}: an arc must start where the machine is (after a tool change, move to its start first)", b.name));
                g.kind = Segment::Kind::Arc;
                g.arc = b;
                g.speed_mm_s = b.feed_mm_min / 60.0;
                g.length = block_length_mm(b);
                if (b.feed_time_s > 0) g.time_s = b.feed_time_s;   // G93
                std::copy(b.end_mm.begin(), b.end_mm.end(), g.to);
                std::copy(b.end_deg.begin(), b.end_deg.end(), g.to + 3);
                add(g);
                break;
            case NcMotion::Dwell:
                g.kind = Segment::Kind::Pause;
                g.length = b.dwell_s;
                add(g);
                break;
            case NcMotion::None:
                break;
        }
    }
    if (spec.machine.max_accel_mm_s2 > 0) plan(out, spec.machine);
    return out;
}

std::size_t run_log(const RunSetup& run, const std::vector<Segment>& segs, const ClientModel& c, std::uint64_t seed,
                    std::size_t max_rows, std::ostream& csv) {
    Machine machine(run, segs);
    Rng rng(seed);
    const MachineModel& m = run.machine;
    fmt::memory_buffer buf;
    std::string rotary_header;
    for (const char axis : run.rotary_axes) rotary_header += fmt::format("{} [deg],", axis);
    fmt::format_to(std::back_inserter(buf), "t_spindle [s],spindle [rpm],t_feed [s],feed [mm/min],t_pos [s],x [mm],y [mm],z [mm],{}{}block\n",
                   rotary_header, run.nc ? "tool," : "");
    double t = c.start_s;
    std::size_t rows = 0;
    // A read returns the state latched at the last tick before the middle of the read; its time
    // stamp is the moment the read returns.
    auto read = [&](int channel) {
        const double d = std::max(0.2 * c.read_s[channel], c.read_s[channel] + c.jitter_s * rng.normal());
        const double sample_t = t + 0.5 * d;
        while (machine.time_s() + m.cnc_period_s <= sample_t) machine.tick();
        t += d;
        return t;
    };
    while (!machine.finished() && (max_rows == 0 || rows < max_rows)) {
        const double t_spindle = read(0);
        const double ripple = std::round((2 * rng.uniform() - 1) * m.spindle_ripple_rpm);
        const bool turning = run.nc ? std::round(machine.spindle_rpm()) != 0 : machine.spindle_rpm() > 0;
        const double rpm = std::round(machine.spindle_rpm()) + (turning ? ripple : 0);
        const double t_feed = read(1);
        const double feed = std::round(machine.actual_feed_mm_min());
        const double t_pos = read(2);
        const double* p = machine.actual();
        const double r = m.position_resolution_mm;
        fmt::format_to(std::back_inserter(buf), "{:.6f},{:.0f},{:.6f},{:.0f},{:.6f},{:.3f},{:.3f},{:.3f},", t_spindle, rpm, t_feed,
                       feed, t_pos, quantise(p[0], r), quantise(p[1], r), quantise(p[2], r));
        // The encoders' resolution; latched with X/Y/Z in the same read.
        for (const char axis : run.rotary_axes)
            fmt::format_to(std::back_inserter(buf), "{:.3f},", quantise(p[3 + (axis - 'a')], m.rotary_resolution_deg) + 0.0);   // no "-0.000"
        if (run.nc) {
            if (machine.tool() >= 0) fmt::format_to(std::back_inserter(buf), "{}", machine.tool());
            buf.push_back(',');
        }
        fmt::format_to(std::back_inserter(buf), "{}\n", textio::csv_field(machine.block_name()));
        ++rows;
        if (c.stall_probability > 0 && rng.uniform() < c.stall_probability) t += c.stall_s * (0.5 + rng.uniform());
        if (buf.size() > (1 << 20)) {
            csv.write(buf.data(), static_cast<std::streamsize>(buf.size()));
            buf.clear();
        }
    }
    csv.write(buf.data(), static_cast<std::streamsize>(buf.size()));
    return rows;
}

}  // namespace

std::size_t synthesize_dry_run(const DryRunSpec& spec, std::ostream& csv) {
    RunSetup run;
    std::copy(spec.start_mm, spec.start_mm + 3, run.start);
    run.machine = spec.machine;
    run.settle_s = spec.settle_s;
    return run_log(run, segments_of(spec), spec.client, spec.seed, spec.max_rows, csv);
}

std::size_t synthesize_nc_dry_run(const NcDryRunSpec& spec, std::ostream& csv) {
    RunSetup run;
    std::copy(spec.start_mm, spec.start_mm + 3, run.start);
    std::copy(spec.start_deg, spec.start_deg + 3, run.start + 3);
    run.rotary_axes = spec.program.rotary_axes;
    run.machine = spec.machine;
    run.settle_s = spec.settle_s;
    run.nc = true;
    return run_log(run, segments_of(spec), spec.client, spec.seed, spec.max_rows, csv);
}

DryRunSpec demo_dry_run_spec() {
    // Stock coordinates (work zero at the stock's min corner); converted to machine coordinates
    // at the end. Tool: flat end mill D 8 mm, so the tool centre stays 4 mm inside pocket walls.
    const double work_zero[3] = {200, -300, -350};
    const double safe_z = 40, feed = 6000;
    const double cx = 52.5, cy = 45;   // pocket centre; pocket 40 x 30 mm, two 3 mm levels
    struct Move {
        bool rapid;
        double x, y, z, f;
    };
    std::vector<Move> moves;
    auto rapid = [&](double x, double y, double z) { moves.push_back({true, x, y, z, 0}); };
    auto cut = [&](double x, double y, double z, double f) { moves.push_back({false, x, y, z, f}); };
    auto pocket_level = [&](double z) {
        // Slot along the centre line, then counter-clockwise rings (a down cut against the
        // pocket walls with M03) stepping over 3 mm until the tool centre reaches the walls.
        cut(cx + 12, cy, z, feed);
        cut(cx - 12, cy, z, feed);
        for (double b : {3.0, 6.0, 9.0, 11.0}) {
            const double a = std::min(16.0, 12.0 + b);
            cut(cx - a, cy - b, z, feed);
            cut(cx + a, cy - b, z, feed);
            cut(cx + a, cy + b, z, feed);
            cut(cx - a, cy + b, z, feed);
            cut(cx - a, cy - b, z, feed);
        }
        rapid(cx - 16, cy - 11, safe_z);
    };
    rapid(cx - 12, cy, safe_z);           // M03 S10000 with the first rapid
    rapid(cx - 12, cy, 31);
    cut(cx, cy, 27, 1500);                // ramp in at about 18 degrees
    pocket_level(27);
    rapid(cx, cy, safe_z);
    rapid(cx, cy, 28);
    cut(cx, cy, 24, 300);                 // plunge into the cleared floor
    pocket_level(24);
    // Outer contour, clockwise (down cut with M03): tool centre 3 mm outside the stock faces,
    // so it removes 1 mm radially over the top 3 mm. The corners are sharp in the program.
    rapid(-3, -15, safe_z);
    rapid(-3, -15, 27);
    cut(-3, 93, 27, feed);
    cut(108, 93, 27, feed);
    cut(108, -3, 27, feed);
    cut(-3, -3, 27, feed);
    cut(-3, 5, 27, feed);
    cut(-15, 5, 27, feed);
    rapid(-15, 5, safe_z);

    DryRunSpec spec;
    spec.start_mm[0] = work_zero[0] + cx - 12;
    spec.start_mm[1] = work_zero[1] - 40;
    spec.start_mm[2] = work_zero[2] + safe_z;
    int n = 10;
    for (const Move& mv : moves) {
        ProgramBlock b;
        b.name = fmt::format("N{}", n);
        n += 10;
        b.rapid = mv.rapid;
        b.target_mm[0] = work_zero[0] + mv.x;
        b.target_mm[1] = work_zero[1] + mv.y;
        b.target_mm[2] = work_zero[2] + mv.z;
        b.feed_mm_min = mv.f;
        spec.program.push_back(b);
    }
    spec.seed = 20240601;
    return spec;
}

namespace {

// A 3-decimal inch post: numbers rounded to 0.001 in, always with a decimal point, no trailing
// zeros ("3.", "-0.053"); words that did not change are left out, except an arc's X/Y/I/J.
class InchPost {
public:
    static std::string number(double v) {
        const double r = std::round(v * 1000) / 1000;
        std::string s = fmt::format("{:.3f}", r == 0 ? 0.0 : r);
        while (s.back() == '0') s.pop_back();
        return s;
    }
    void comment(const std::string& text) { out_ += text + "\n"; }
    void block(const std::string& words) {
        out_ += fmt::format("N{} {}\n", n_, words);
        n_ += 10;
    }
    // Forget the modal state (after a tool change the post writes everything again).
    void reset() {
        g_.clear();
        xyz_ = {"", "", ""};
        f_.clear();
    }
    // A line or rapid; `extra` goes after the motion words (S, M, H).
    void move(const std::string& g, std::optional<double> x, std::optional<double> y, std::optional<double> z,
              std::optional<double> f_ipm = std::nullopt, const std::string& head = "", const std::string& extra = "") {
        std::string w = g != g_ ? g : "";
        g_ = g;
        if (!head.empty()) {
            if (!w.empty()) w += ' ';
            w += head;
        }
        axes(w, {x, y, z}, false);
        feed(w, f_ipm);
        if (!extra.empty()) w += " " + extra;
        if (!w.empty()) block(w);
    }
    // An arc with absolute centre (cx, cy); z for a helix.
    void arc(const std::string& g, double x, double y, std::optional<double> z, double cx, double cy, std::optional<double> f_ipm = std::nullopt) {
        std::string w;
        if (g != g_) w += g;
        g_ = g;
        axes(w, {x, y, z}, true);
        w += " I" + number(cx) + " J" + number(cy);
        feed(w, f_ipm);
        block(w);
    }
    const std::string& text() const { return out_; }

private:
    void axes(std::string& w, std::array<std::optional<double>, 3> v, bool force_xy) {
        for (int a = 0; a < 3; ++a) {
            if (!v[a]) continue;
            const std::string t = number(*v[a]);
            if (t == xyz_[a] && !(force_xy && a < 2)) continue;
            if (!w.empty()) w += ' ';
            w += "XYZ"[a];
            w += t;
            xyz_[a] = t;
        }
    }
    void feed(std::string& w, std::optional<double> f_ipm) {
        if (!f_ipm) return;
        const std::string t = fmt::format("F{:.1f}", *f_ipm);
        if (t == f_) return;
        w += " " + (t.size() > 2 && t.substr(t.size() - 2) == ".0" ? t.substr(0, t.size() - 1) : t);
        f_ = t;
    }
    std::string out_;
    int n_ = 10;
    std::string g_, f_;
    std::array<std::string, 3> xyz_{"", "", ""};
};

}  // namespace

std::string demo2_program_text() {
    InchPost post;
    post.comment("%");
    post.comment("O2000 (CUTLOAD DEMO 2: FACE, POCKET, HOLES)");
    post.comment("(INCH, 3 DECIMALS. THE CONTROL IS SET TO INCH AND TO ABSOLUTE ARC CENTRES)");
    post.comment("(G54 = STOCK TOP AT THE MIN X/Y CORNER. STOCK 6. X 4. X 1.5 + 0.02 FACING ALLOWANCE)");
    post.comment("G17 G40 G49 G80 G90 G94");

    // T1: face mill D2. (5 inserts), three passes along X, 1.4 in apart, 0.02 in deep.
    post.block("T1 M06 (FACE MILL D2. 5 INSERTS)");
    post.move("G00", -1.2, 0.6, std::nullopt, std::nullopt, "G90 G54", "S6000 M03");
    post.move("G00", std::nullopt, std::nullopt, 1.0, std::nullopt, "G43", "H1");
    post.move("G00", std::nullopt, std::nullopt, 0.1);
    post.move("G01", std::nullopt, std::nullopt, 0.0, 40.0);
    post.move("G01", 7.2, std::nullopt, std::nullopt, 150.0);
    post.move("G01", std::nullopt, 2.0, std::nullopt);
    post.move("G01", -1.2, std::nullopt, std::nullopt);
    post.move("G01", std::nullopt, 3.4, std::nullopt);
    post.move("G01", 7.2, std::nullopt, std::nullopt);
    post.move("G00", std::nullopt, std::nullopt, 1.0);
    post.block("M05");
    post.block("G53 Z0.");

    // T2: end mill D.5 (3 flutes). A 2.5 x 1.5 in pocket with R.375 corners, 0.25 in deep in two
    // levels, turned 20 deg about (3, 2): a helical entry of radius .1 (two turns), then two
    // counter-clockwise rounded-rectangle rings (tool centre half-sizes .7 x .2 and 1. x .5,
    // corner radius .125). Turned, every coordinate is rounded by the post.
    post.reset();
    post.block("T2 M06 (END MILL D.5 3 FLUTES)");
    const double cx = 3.0, cy = 2.0, turn = 20.0 * std::numbers::pi / 180;
    auto at = [&](double u, double v) {
        return std::array<double, 2>{cx + u * std::cos(turn) - v * std::sin(turn), cy + u * std::sin(turn) + v * std::cos(turn)};
    };
    const auto helix0 = at(0.1, 0.0);
    post.move("G00", helix0[0], helix0[1], std::nullopt, std::nullopt, "G90 G54", "S8000 M03");
    post.move("G00", std::nullopt, std::nullopt, 1.0, std::nullopt, "G43", "H2");
    post.move("G00", std::nullopt, std::nullopt, 0.1);
    auto ring = [&](double hx, double hy, double rc) {
        struct Step {
            bool arc;
            double u, v, cu, cv;
        };
        const Step steps[] = {{false, hx, hy - rc, 0, 0},          {true, hx - rc, hy, hx - rc, hy - rc},
                              {false, -hx + rc, hy, 0, 0},         {true, -hx, hy - rc, -hx + rc, hy - rc},
                              {false, -hx, -hy + rc, 0, 0},        {true, -hx + rc, -hy, -hx + rc, -hy + rc},
                              {false, hx - rc, -hy, 0, 0},         {true, hx, -hy + rc, hx - rc, -hy + rc},
                              {false, hx, 0, 0, 0}};
        for (const Step& st : steps) {
            const auto p = at(st.u, st.v);
            if (st.arc) {
                const auto c = at(st.cu, st.cv);
                post.arc("G03", p[0], p[1], std::nullopt, c[0], c[1]);
            } else {
                post.move("G01", p[0], p[1], std::nullopt);
            }
        }
    };
    for (const double floor : {-0.125, -0.25}) {
        const double top = floor + 0.125 + 0.02;
        post.move("G00", helix0[0], helix0[1], std::nullopt);
        post.move("G01", std::nullopt, std::nullopt, top, 20.0);
        post.arc("G03", helix0[0], helix0[1], (top + floor) / 2, cx, cy, 40.0);
        post.arc("G03", helix0[0], helix0[1], floor, cx, cy);
        post.arc("G03", helix0[0], helix0[1], std::nullopt, cx, cy);
        const auto r1 = at(0.7, 0.0);
        post.move("G01", r1[0], r1[1], std::nullopt, 80.0);
        ring(0.7, 0.2, 0.125);
        const auto r2 = at(1.0, 0.0);
        post.move("G01", r2[0], r2[1], std::nullopt);
        ring(1.0, 0.5, 0.125);
        post.move("G00", std::nullopt, std::nullopt, 0.1);
    }
    post.move("G00", std::nullopt, std::nullopt, 1.0);
    post.block("M05");
    post.block("G53 Z0.");

    // T3: drill D.25 (118 deg point), four holes 0.4 in deep pecked by .1 (G83), R .1 above the
    // top; G99 between the holes, G98 back to the initial level after the last.
    post.reset();
    post.block("T3 M06 (DRILL D.25 118 DEG)");
    post.move("G00", 0.6, 0.6, std::nullopt, std::nullopt, "G90 G54", "S3000 M03");
    post.move("G00", std::nullopt, std::nullopt, 1.0, std::nullopt, "G43", "H3");
    post.block("G99 G83 X0.6 Y0.6 Z-0.4 R0.1 Q0.1 F12.");
    post.block("X5.4");
    post.block("Y3.4");
    post.block("G98 X0.6");
    post.block("G80");
    post.block("M05");
    post.block("G53 Z0.");
    post.block("M30");
    post.comment("%");
    return post.text();
}

NcReadOptions demo2_read_options() {
    NcReadOptions o;
    o.work_offsets_mm["G54"] = {250, -300, -420};   // minus setup.offset_mm of data/demo2_run.json
    o.program_units = ProgramUnits::Inch;
    o.arc_centers = ArcCenters::Absolute;
    o.start_mm = std::array<double, 3>{450, 0, 0};   // the tool-change position, where the log starts
    return o;
}

NcDryRunSpec demo2_dry_run_spec() {
    NcDryRunSpec spec;
    spec.program = parse_nc_program(demo2_program_text(), "demo2_program.nc", demo2_read_options());
    const auto start = *demo2_read_options().start_mm;
    std::copy(start.begin(), start.end(), spec.start_mm);
    std::copy(start.begin(), start.end(), spec.tool_change.position_mm);
    spec.tool_change.time_s = 4.0;
    spec.machine.max_accel_mm_s2 = 2500;   // about 0.25 g: a mid-size vertical machining centre
    spec.machine.corner_speed_step_mm_min = 600;
    spec.client.stall_probability = 0.004;
    spec.client.stall_s = 0.03;
    spec.seed = 20250212;
    return spec;
}

std::string demo3_program_text() {
    // Written as a shop post writes a C-table program in machine-axis form: the rotary move in
    // G93 (the post works out 1/F from the arc the tool travels on the part), the return turn in
    // G94 with the control's combined feed. Ring groove: tool centre at R35 then R38, D6 tool, so
    // the groove spans R32..R41, 2 mm deep.
    return "%\n"
           "O3000 (CUTLOAD DEMO 3: A RING GROOVE CUT BY TURNING THE C TABLE)\n"
           "(AC TABLE-TABLE MACHINE, MACHINE-AXIS FORM: A0 KEEPS THE TOOL VERTICAL, C TURNS THE PART)\n"
           "(G54 = THE C LINE ON THE STOCK TOP, MACHINE X-350. Y-275. Z-460.; X/Y/Z ARE THE TOOL TIP)\n"
           "(T1 FLAT END MILL D6. 2 FLUTES)\n"
           "N10 G17 G21 G40 G49 G80 G90 G94\n"
           "N20 G00 G54 X35. Y0. A0. C0. S8000 M03\n"
           "N30 Z5.\n"
           "N40 G01 Z-2. F300\n"
           "N50 G93 G01 C360. F13.642 (ONE TURN IN 1/F MIN: 3000 MM/MIN ALONG THE R35 ARC)\n"
           "N60 G94 X38. F600 (STEP OUT 3 MM)\n"
           "N70 C0. F3600 (ONE TURN BACK, 3600 DEG/MIN: 2388 MM/MIN ALONG THE R38 ARC)\n"
           "N80 G00 Z5.\n"
           "N90 Z60.\n"
           "N100 M05\n"
           "N110 M30\n"
           "%\n";
}

NcReadOptions demo3_read_options() {
    NcReadOptions o;
    o.work_offsets_mm["G54"] = {-350, -275, -460};   // the C line (data/machines/ac_table_table.json) on the stock top
    o.start_mm = std::array<double, 3>{-315, -275, -400};   // above the groove's start, where the log starts
    o.rotary_axes = "AC";                              // the AC machine's rotary axes
    o.rotary_feed = RotaryFeed::Combined;
    return o;
}

namespace {

// The five-axis demos' dry run: `text` read with `read` on demo2's machine and client (for the
// table, 2500 deg/s^2), starting where the options start.
NcDryRunSpec five_axis_demo_spec(const std::string& text, const std::string& name, const NcReadOptions& read,
                                 std::uint64_t seed) {
    NcDryRunSpec spec;
    spec.program = parse_nc_program(text, name, read);
    const auto start = *read.start_mm;
    std::copy(start.begin(), start.end(), spec.start_mm);
    spec.machine.max_accel_mm_s2 = 2500;
    spec.machine.corner_speed_step_mm_min = 600;
    spec.client.stall_probability = 0.004;
    spec.client.stall_s = 0.03;
    spec.seed = seed;
    return spec;
}

}  // namespace

NcDryRunSpec demo3_dry_run_spec() {
    return five_axis_demo_spec(demo3_program_text(), "demo3_program.nc", demo3_read_options(), 20250315);
}

std::string demo4_program_text() {
    // As a post for a trunnion machine without tool-centre-point control writes it: program zero at
    // the rotary axes' intersection, the table indexed first, then X/Y/Z of the tool tip in machine
    // axes with the part tilted, to three decimals. The pass positions are the part's
    // (stock y 20, 22, 24 mm; tip 0.5 mm below the top face at stock z 29.5) through the machine's
    // inverse kinematics at A-20 C0; the part's X runs along the machine's X, so each pass is one
    // G01 in X, and the tool enters and leaves along its own axis (machine Z).
    return "%\n"
           "O4000 (CUTLOAD DEMO 4: 3+2 FINISHING, BALL END MILL LEANING 20 DEG)\n"
           "(AC TABLE-TABLE MACHINE, MACHINE-AXIS FORM: A-20. TILTS THE PART, C0.)\n"
           "(G54 = THE ROTARY AXES' INTERSECTION, MACHINE X-350. Y-275. Z-560.; X/Y/Z ARE THE TOOL TIP)\n"
           "(T1 BALL END MILL D10. 2 FLUTES)\n"
           "N10 G17 G21 G40 G49 G80 G90 G94\n"
           "N20 G00 G54 X-58. Y-62.222 Z150. A0. C0. S8000 M03\n"
           "N30 A-20. (INDEX IN THE AIR)\n"
           "N40 Z90.\n"
           "N50 G01 Z83.239 F500\n"
           "N60 X58. F2000 (PASS 1)\n"
           "N70 G00 Z90.\n"
           "N80 X-58. Y-60.342\n"
           "N90 G01 Z83.923 F500\n"
           "N100 X58. F2000 (PASS 2)\n"
           "N110 G00 Z90.\n"
           "N120 X-58. Y-58.463\n"
           "N130 G01 Z84.607 F500\n"
           "N140 X58. F2000 (PASS 3)\n"
           "N150 G00 Z150.\n"
           "N160 A0.\n"
           "N170 M05\n"
           "N180 M30\n"
           "%\n";
}

NcReadOptions demo4_read_options() {
    NcReadOptions o;
    o.work_offsets_mm["G54"] = {-350, -275, -560};   // the rotary axes' intersection (data/machines/ac_table_table.json)
    o.start_mm = std::array<double, 3>{-408, -337.222, -410};   // above the first pass, where the log starts
    o.rotary_axes = "AC";
    o.rotary_feed = RotaryFeed::Combined;
    return o;
}

NcDryRunSpec demo4_dry_run_spec() {
    return five_axis_demo_spec(demo4_program_text(), "demo4_program.nc", demo4_read_options(), 20261128);
}

}  // namespace cutload::motion_io
