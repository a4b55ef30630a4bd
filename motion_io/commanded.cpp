#include "motion_io/commanded.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>

namespace cutload::motion_io {
namespace {

double block_speed_mm_s(const NcBlock& b, std::size_t i, const CommandedOptions& opt) {
    if (b.motion == NcMotion::Rapid) return opt.rapid_mm_min / 60.0;
    const double f = i < opt.feed_mm_min.size() && opt.feed_mm_min[i] > 0 ? opt.feed_mm_min[i] : b.feed_mm_min;
    return f / 60.0;
}

}  // namespace

std::vector<std::string> program_block_names(const NcProgram& program) {
    std::vector<std::string> names;
    for (const NcBlock& b : program.blocks)
        if (std::find(names.begin(), names.end(), b.name) == names.end()) names.push_back(b.name);
    return names;
}

std::vector<double> commanded_durations_s(const NcProgram& program, const CommandedOptions& opt) {
    if (!(opt.rapid_mm_min > 0)) throw std::invalid_argument("commanded motion: rapid rate must be > 0");
    std::vector<double> d(program.blocks.size(), 0.0);
    for (std::size_t i = 0; i < program.blocks.size(); ++i) {
        const NcBlock& b = program.blocks[i];
        if (b.motion == NcMotion::Dwell) {
            d[i] = b.dwell_s;
        } else if (block_moves(b) && (b.feed_time_s > 0 || block_turns(b))) {
            // Timed by G93 or by the rotary feed rule; a feed override scales a G94 block's time.
            d[i] = block_time_s(b, opt.rapid_mm_min);
            const bool overridden = i < opt.feed_mm_min.size() && opt.feed_mm_min[i] > 0;
            if (overridden && b.motion != NcMotion::Rapid && !b.inverse_time) d[i] *= b.feed_mm_min / opt.feed_mm_min[i];
        } else if (block_moves(b)) {
            d[i] = block_length_mm(b) / block_speed_mm_s(b, i, opt);
        }
    }
    return d;
}

double commanded_sample_count(const NcProgram& program, const CommandedOptions& opt) {
    if (!(opt.step_s > 0)) throw std::invalid_argument("commanded motion: step must be > 0");
    double total_s = 0;
    for (double d : commanded_durations_s(program, opt)) total_s += d;
    return std::floor(total_s / opt.step_s) + 2;
}

MotionModel commanded_motion(const NcProgram& program, const CommandedOptions& opt) {
    // Estimated before anything is built: a typo in a feed or a position must not run away.
    const double samples = commanded_sample_count(program, opt);
    if (samples > opt.max_samples)
        throw NcProgramError(fmt::format("{}: the commanded motion would take {:.4g} samples at {:g} ms, above the limit of {:.4g}",
                                         program.file, samples, opt.step_s * 1e3, opt.max_samples));
    const std::vector<double> dur = commanded_durations_s(program, opt);
    std::vector<std::size_t> timed;   // blocks that take time, in order
    std::vector<double> t_begin;
    double total_s = 0;
    for (std::size_t i = 0; i < dur.size(); ++i)
        if (dur[i] > 0) {
            timed.push_back(i);
            t_begin.push_back(total_s);
            total_s += dur[i];
        }
    if (timed.empty()) throw std::invalid_argument(fmt::format("{}: the program has no motion", program.file));

    MotionModel m;
    m.step_s = opt.step_s;
    m.block_names = program_block_names(program);
    std::map<std::string, std::int32_t> index;
    for (std::size_t k = 0; k < m.block_names.size(); ++k) index[m.block_names[k]] = static_cast<std::int32_t>(k);

    const auto n = static_cast<std::size_t>(std::floor(total_s / opt.step_s)) + 1;
    std::size_t seg = 0;
    for (std::size_t k = 0; k <= n; ++k) {
        const double t = static_cast<double>(k) * opt.step_s;
        while (seg + 1 < timed.size() && t >= t_begin[seg + 1]) ++seg;
        const NcBlock& b = program.blocks[timed[seg]];
        double pos[3], tangent[3];
        const double u = (t - t_begin[seg]) / dur[timed[seg]];
        // The last sample is the machine at rest at the program's end.
        const bool at_rest = k == n || b.motion == NcMotion::Dwell;
        block_point(b, b.motion == NcMotion::Dwell ? 1.0 : u, pos, tangent);
        // A block timed by G93 or the rotary feed rule runs its X/Y/Z path in its own time.
        const bool own_time = b.feed_time_s > 0 || block_turns(b);
        const double speed = at_rest ? 0.0 : own_time ? block_length_mm(b) / dur[timed[seg]] : block_speed_mm_s(b, timed[seg], opt);
        m.t_s.push_back(t);
        m.x_mm.push_back(pos[0]);
        m.y_mm.push_back(pos[1]);
        m.z_mm.push_back(pos[2]);
        m.vx_mm_s.push_back(speed * tangent[0]);
        m.vy_mm_s.push_back(speed * tangent[1]);
        m.vz_mm_s.push_back(speed * tangent[2]);
        m.spindle_rpm.push_back(b.spindle_rpm);
        const double angle = k == 0 ? 0.0 : m.spindle_angle_deg.back() + 6.0 * 0.5 * (m.spindle_rpm[k - 1] + b.spindle_rpm) * opt.step_s;
        m.spindle_angle_deg.push_back(angle);
        m.block.push_back(index.at(b.name));
        m.tool.push_back(b.tool);
        // Joint space: each rotary axis runs linearly over its block (machine-axis form).
        for (const char axis : program.rotary_axes) {
            const auto r = static_cast<std::size_t>(axis - 'a');
            const double u_r = b.motion == NcMotion::Dwell ? 1.0 : std::clamp(u, 0.0, 1.0);
            m.rot_deg[r].push_back(b.start_deg[r] + u_r * (b.end_deg[r] - b.start_deg[r]));
            m.rot_vel_deg_s[r].push_back(at_rest ? 0.0 : (b.end_deg[r] - b.start_deg[r]) / dur[timed[seg]]);
        }
    }
    m.session_start = {0};
    return m;
}

}  // namespace cutload::motion_io
