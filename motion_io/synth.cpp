#include "motion_io/synth.hpp"

#include "textio/csv.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <iterator>
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

class MovingAverage {
public:
    MovingAverage(int n, const double start[3]) : ring_(static_cast<std::size_t>(std::max(n, 1))) {
        for (auto& r : ring_) std::copy(start, start + 3, r.begin());
        for (int a = 0; a < 3; ++a) sum_[a] = start[a] * static_cast<double>(ring_.size());
    }
    void push(const double in[3], double out[3]) {
        auto& slot = ring_[i_];
        for (int a = 0; a < 3; ++a) {
            sum_[a] += in[a] - slot[a];
            slot[a] = in[a];
            out[a] = sum_[a] / static_cast<double>(ring_.size());
        }
        i_ = (i_ + 1) % ring_.size();
    }

private:
    std::vector<std::array<double, 3>> ring_;
    std::size_t i_ = 0;
    double sum_[3] = {0, 0, 0};
};

// The machine, advanced one CNC period at a time.
class Machine {
public:
    explicit Machine(const DryRunSpec& spec)
        : spec_(spec), m_(spec.machine), ma1_(m_.accdec_ticks[0], spec.start_mm), ma2_(m_.accdec_ticks[1], spec.start_mm) {
        std::copy(spec.start_mm, spec.start_mm + 3, cmd_);
        std::copy(spec.start_mm, spec.start_mm + 3, act_);
        std::copy(spec.start_mm, spec.start_mm + 3, prev_act_);
        std::copy(spec.start_mm, spec.start_mm + 3, seg_from_);
        if (!spec.program.empty()) start_block();
    }

    // Advances by one CNC period; the latched state is what a read sees until the next tick.
    void tick() {
        const double T = m_.cnc_period_s;
        ++ticks_;
        interpolate(T);
        double f1[3], f2[3];
        ma1_.push(cmd_, f1);
        ma2_.push(f1, f2);
        const double k = 1.0 - std::exp(-T / m_.servo_time_constant_s);
        std::copy(act_, act_ + 3, prev_act_);
        for (int a = 0; a < 3; ++a) act_[a] += (f2[a] - act_[a]) * k;
        if (program_done_) settle_ticks_++;
    }

    double time_s() const { return static_cast<double>(ticks_) * m_.cnc_period_s; }
    bool finished() const { return program_done_ && settle_ticks_ * m_.cnc_period_s >= spec_.settle_s; }
    const double* actual_mm() const { return act_; }
    double actual_feed_mm_min() const {
        double d2 = 0;
        for (int a = 0; a < 3; ++a) d2 += (act_[a] - prev_act_[a]) * (act_[a] - prev_act_[a]);
        return std::sqrt(d2) / m_.cnc_period_s * 60.0;
    }
    double spindle_rpm() const {
        return m_.spindle_ramp_s > 0 ? m_.spindle_rpm * std::min(1.0, time_s() / m_.spindle_ramp_s) : m_.spindle_rpm;
    }
    const std::string& block_name() const {
        static const std::string none;
        return spec_.program.empty() ? none : spec_.program[std::min(block_, spec_.program.size() - 1)].name;
    }

private:
    void start_block() {
        const ProgramBlock& b = spec_.program[block_];
        std::copy(cmd_, cmd_ + 3, seg_from_);
        seg_len_ = std::sqrt((b.target_mm[0] - cmd_[0]) * (b.target_mm[0] - cmd_[0]) +
                             (b.target_mm[1] - cmd_[1]) * (b.target_mm[1] - cmd_[1]) +
                             (b.target_mm[2] - cmd_[2]) * (b.target_mm[2] - cmd_[2]));
        seg_s_ = 0;
        const double f = b.rapid ? m_.rapid_mm_min : b.feed_mm_min;
        if (!(f > 0)) throw std::invalid_argument(fmt::format("block {}: feed must be > 0", b.name));
        speed_mm_s_ = f / 60.0;
    }

    // Continuous-path interpolation: the distance left over at a block end carries into the next.
    void interpolate(double T) {
        double travel = speed_mm_s_ * T;
        while (!program_done_) {
            const ProgramBlock& b = spec_.program[block_];
            const double left = seg_len_ - seg_s_;
            if (travel < left) {
                seg_s_ += travel;
                for (int a = 0; a < 3; ++a) cmd_[a] = seg_from_[a] + (b.target_mm[a] - seg_from_[a]) * seg_s_ / seg_len_;
                return;
            }
            const double used_time = left / speed_mm_s_;
            std::copy(b.target_mm, b.target_mm + 3, cmd_);
            if (block_ + 1 >= spec_.program.size()) {
                program_done_ = true;
                return;
            }
            const double time_left = travel / speed_mm_s_ - used_time;
            ++block_;
            start_block();
            travel = time_left * speed_mm_s_;
        }
    }

    const DryRunSpec& spec_;
    const MachineModel& m_;
    MovingAverage ma1_, ma2_;
    double cmd_[3], act_[3], prev_act_[3], seg_from_[3];
    double seg_len_ = 0, seg_s_ = 0, speed_mm_s_ = 1;
    std::size_t block_ = 0;
    std::size_t ticks_ = 0;
    std::size_t settle_ticks_ = 0;
    bool program_done_ = false;
};

double quantise(double v, double step) { return step > 0 ? std::round(v / step) * step : v; }

}  // namespace

std::size_t synthesize_dry_run(const DryRunSpec& spec, std::ostream& csv) {
    Machine machine(spec);
    Rng rng(spec.seed);
    const ClientModel& c = spec.client;
    const MachineModel& m = spec.machine;
    fmt::memory_buffer buf;
    fmt::format_to(std::back_inserter(buf), "t_spindle [s],spindle [rpm],t_feed [s],feed [mm/min],t_pos [s],x [mm],y [mm],z [mm],block\n");
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
    while (!machine.finished() && (spec.max_rows == 0 || rows < spec.max_rows)) {
        const double t_spindle = read(0);
        const double ripple = std::round((2 * rng.uniform() - 1) * m.spindle_ripple_rpm);
        const double rpm = std::round(machine.spindle_rpm()) + (machine.spindle_rpm() > 0 ? ripple : 0);
        const double t_feed = read(1);
        const double feed = std::round(machine.actual_feed_mm_min());
        const double t_pos = read(2);
        const double* p = machine.actual_mm();
        const double r = m.position_resolution_mm;
        fmt::format_to(std::back_inserter(buf), "{:.6f},{:.0f},{:.6f},{:.0f},{:.6f},{:.3f},{:.3f},{:.3f},{}\n", t_spindle,
                       rpm, t_feed, feed, t_pos, quantise(p[0], r), quantise(p[1], r), quantise(p[2], r),
                       textio::csv_field(machine.block_name()));
        ++rows;
        if (buf.size() > (1 << 20)) {
            csv.write(buf.data(), static_cast<std::streamsize>(buf.size()));
            buf.clear();
        }
    }
    csv.write(buf.data(), static_cast<std::streamsize>(buf.size()));
    return rows;
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

}  // namespace cutload::motion_io
