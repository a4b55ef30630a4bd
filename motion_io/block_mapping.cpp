#include "motion_io/block_mapping.hpp"

#include "motion_io/commanded.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <stdexcept>

namespace cutload::motion_io {
namespace {

// The programmed path as chords in arc-length order (lines exact, arcs within 2 um).
struct Chord {
    double p0[3], d[3];   // start and direction * length
    double s0_mm, len_mm;
    std::int32_t block;   // index into program.blocks
};

std::vector<Chord> program_chords(const NcProgram& program) {
    constexpr double kArcTolerance_mm = 0.002;
    std::vector<Chord> out;
    double s = 0;
    for (std::size_t i = 0; i < program.blocks.size(); ++i) {
        const NcBlock& b = program.blocks[i];
        if (!block_moves(b)) continue;
        const double len = block_length_mm(b);
        int pieces = 1;
        if (b.motion == NcMotion::ArcCw || b.motion == NcMotion::ArcCcw) {
            const int a = b.plane_axes[0], c = b.plane_axes[1];
            const double r = std::max(1e-6, std::hypot(b.start_mm[a] - b.center_mm[a], b.start_mm[c] - b.center_mm[c]));
            const double max_angle = 2 * std::acos(std::max(0.0, 1 - kArcTolerance_mm / r));
            pieces = std::clamp(static_cast<int>(std::ceil(std::abs(b.sweep_rad) / std::max(max_angle, 1e-6))), 1, 100000);
        }
        double prev[3], tangent[3];
        block_point(b, 0.0, prev, tangent);
        for (int k = 1; k <= pieces; ++k) {
            double next[3];
            block_point(b, double(k) / pieces, next, tangent);
            Chord ch;
            for (int a = 0; a < 3; ++a) {
                ch.p0[a] = prev[a];
                ch.d[a] = next[a] - prev[a];
                prev[a] = next[a];
            }
            ch.len_mm = std::hypot(ch.d[0], ch.d[1], ch.d[2]);
            ch.s0_mm = s;
            ch.block = static_cast<std::int32_t>(i);
            s += len / pieces;   // arc length, so chords of a block meet the block's length exactly
            out.push_back(ch);
        }
    }
    return out;
}

struct Match {
    double dist_mm = std::numeric_limits<double>::infinity();
    double s_mm = 0;
    std::size_t chord = 0;
};

// Nearest point of chord c to p with arc length in [s_lo, s_hi].
void consider(const Chord& c, std::size_t idx, const double p[3], double s_lo, double s_hi, Match& best) {
    double u = 0;
    if (c.len_mm > 0) {
        // Arc length runs linearly along the chord (an arc's chords are within 2 um of it).
        const double u_lo = std::clamp((s_lo - c.s0_mm) / c.len_mm, 0.0, 1.0);
        const double u_hi = std::clamp((s_hi - c.s0_mm) / c.len_mm, 0.0, 1.0);
        const double dd = c.len_mm * c.len_mm;
        u = ((p[0] - c.p0[0]) * c.d[0] + (p[1] - c.p0[1]) * c.d[1] + (p[2] - c.p0[2]) * c.d[2]) / dd;
        u = std::clamp(u, u_lo, u_hi);
    }
    const double q[3] = {c.p0[0] + u * c.d[0], c.p0[1] + u * c.d[1], c.p0[2] + u * c.d[2]};
    const double dist = std::hypot(p[0] - q[0], p[1] - q[1], p[2] - q[2]);
    // Ties go to the earlier point: where the program turns back on itself the tool is still on
    // the earlier block until it has visibly left it.
    if (dist < best.dist_mm - 1e-6) {
        best.dist_mm = dist;
        best.s_mm = c.s0_mm + u * c.len_mm;
        best.chord = idx;
    }
}

std::size_t chord_at(const std::vector<Chord>& chords, double s_mm) {
    const auto it = std::upper_bound(chords.begin(), chords.end(), s_mm, [](double s, const Chord& c) { return s < c.s0_mm; });
    return it == chords.begin() ? 0 : static_cast<std::size_t>(it - chords.begin() - 1);
}

// Geometric matching only (program_block, distance_mm, path_mm).
void match_geometry(const MotionModel& motion, const std::vector<Chord>& chords, const BlockMappingOptions& opt,
                    BlockMapping& out) {
    const std::size_t n = motion.size();
    out.program_block.assign(n, -1);
    out.distance_mm.assign(n, std::numeric_limits<double>::quiet_NaN());
    out.path_mm.assign(n, std::numeric_limits<double>::quiet_NaN());
    if (chords.empty()) return;
    std::size_t session = 0;
    double s_prev = 0, travel_since_search = 0;
    double prev[3] = {0, 0, 0};
    for (std::size_t i = 0; i < n; ++i) {
        const double p[3] = {motion.x_mm[i], motion.y_mm[i], motion.z_mm[i]};
        const bool session_begins = session < motion.session_start.size() && motion.session_start[session] == i;
        double travel = 0;
        if (session_begins) {
            ++session;
            s_prev = 0;   // a new recording may run the program from its start again
            travel_since_search = std::numeric_limits<double>::infinity();
        } else {
            travel = std::hypot(p[0] - prev[0], p[1] - prev[1], p[2] - prev[2]);
        }
        std::copy(p, p + 3, prev);
        const double s_hi = s_prev + 3 * travel + opt.slack_mm;
        Match best;
        for (std::size_t c = chord_at(chords, s_prev); c < chords.size() && chords[c].s0_mm <= s_hi; ++c)
            consider(chords[c], c, p, s_prev, s_hi, best);
        travel_since_search += travel;
        if (best.dist_mm > opt.max_distance_mm && travel_since_search >= 1.0) {
            // Lost (the log left the program, or started elsewhere): look ahead along the whole
            // rest of the program, at most once per mm of travel.
            travel_since_search = 0;
            for (std::size_t c = chord_at(chords, s_prev); c < chords.size(); ++c)
                consider(chords[c], c, p, s_prev, std::numeric_limits<double>::infinity(), best);
        }
        if (best.dist_mm > opt.max_distance_mm) continue;
        s_prev = best.s_mm;
        out.program_block[i] = chords[best.chord].block;
        out.distance_mm[i] = best.dist_mm;
        out.path_mm[i] = best.s_mm;
    }
}

// Block channel from the geometric match shifted by the lead, within each session.
void apply_lead(const MotionModel& motion, const NcProgram& program, double lead_s, BlockMapping& out) {
    std::map<std::string, std::int32_t> index;
    for (std::size_t k = 0; k < out.block_names.size(); ++k) index[out.block_names[k]] = static_cast<std::int32_t>(k);
    const std::size_t n = motion.size();
    const auto lead = static_cast<std::size_t>(std::max(0L, std::lround(lead_s / motion.step_s)));
    out.block.assign(n, -1);
    std::size_t session_end = 0, session = 0;
    for (std::size_t i = 0; i < n; ++i) {
        if (i >= session_end) {
            ++session;
            session_end = session < motion.session_start.size() ? motion.session_start[session] : n;
        }
        const std::size_t j = std::min(i + lead, session_end - 1);
        const std::int32_t pb = out.program_block[j] >= 0 ? out.program_block[j] : out.program_block[i];
        if (pb >= 0) out.block[i] = index.at(program.blocks[static_cast<std::size_t>(pb)].name);
    }
}

bool has_block_channel(const MotionModel& m) {
    return !m.block_names.empty() && std::any_of(m.block.begin(), m.block.end(), [](std::int32_t b) { return b >= 0; });
}

void fill_quality(const MotionModel& motion, const NcProgram& program, const std::vector<Chord>& chords, BlockMapping& out) {
    BlockMappingQuality& q = out.quality;
    q.samples = motion.size();
    std::vector<double> d;
    double s_max = 0;
    std::vector<bool> seen(program.blocks.size(), false);
    for (std::size_t i = 0; i < motion.size(); ++i) {
        if (out.program_block[i] < 0) continue;
        d.push_back(out.distance_mm[i]);
        s_max = std::max(s_max, out.path_mm[i]);
        seen[static_cast<std::size_t>(out.program_block[i])] = true;
    }
    q.matched = d.size();
    q.matched_fraction = q.samples ? double(q.matched) / double(q.samples) : 0.0;
    if (!d.empty()) {
        double sum = 0;
        for (double v : d) sum += v;
        q.mean_distance_mm = sum / double(d.size());
        q.max_distance_mm = *std::max_element(d.begin(), d.end());
        const std::size_t k = std::min(d.size() - 1, static_cast<std::size_t>(0.95 * double(d.size())));
        std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(k), d.end());
        q.p95_distance_mm = d[k];
    }
    const double total = chords.empty() ? 0.0 : chords.back().s0_mm + chords.back().len_mm;
    q.coverage = total > 0 ? std::min(1.0, s_max / total) : 0.0;
    for (std::size_t i = 0; i < program.blocks.size(); ++i)
        if (block_moves(program.blocks[i]) && !seen[i]) q.blocks_without_samples.push_back(program.blocks[i].name);
    if (has_block_channel(motion)) q.agreement = block_agreement(motion, out.block, out.block_names);
}

}  // namespace

double block_agreement(const MotionModel& a, const std::vector<std::int32_t>& b_block, const std::vector<std::string>& b_names) {
    std::size_t compared = 0, same = 0;
    for (std::size_t i = 0; i < a.size() && i < b_block.size(); ++i) {
        if (a.block[i] < 0) continue;
        ++compared;
        if (b_block[i] >= 0 && a.block_names[static_cast<std::size_t>(a.block[i])] == b_names[static_cast<std::size_t>(b_block[i])]) ++same;
    }
    return compared ? double(same) / double(compared) : 0.0;
}

BlockMapping map_blocks(const MotionModel& motion, const NcProgram& program, const BlockMappingOptions& opt) {
    if (!(opt.max_distance_mm > 0) || opt.lead_s < 0 || opt.slack_mm < 0)
        throw std::invalid_argument("block mapping: max distance must be > 0, lead and slack >= 0");
    const std::vector<Chord> chords = program_chords(program);
    BlockMapping out;
    out.block_names = program_block_names(program);
    match_geometry(motion, chords, opt, out);
    apply_lead(motion, program, opt.lead_s, out);
    fill_quality(motion, program, chords, out);
    return out;
}

MotionModel with_mapped_blocks(MotionModel motion, const BlockMapping& mapping) {
    motion.block = mapping.block;
    motion.block_names = mapping.block_names;
    return motion;
}

double estimate_block_lead_s(const MotionModel& logged, const NcProgram& program, const BlockMappingOptions& opt,
                             double max_lead_s) {
    if (!has_block_channel(logged)) throw std::invalid_argument("estimate_block_lead_s: the log has no block channel");
    BlockMappingOptions o = opt;
    o.lead_s = 0;
    const std::vector<Chord> chords = program_chords(program);
    BlockMapping m;
    m.block_names = program_block_names(program);
    match_geometry(logged, chords, o, m);
    double best_lead = 0, best_agreement = -1;
    const auto steps = static_cast<long>(std::floor(max_lead_s / logged.step_s + 1e-9));
    for (long k = 0; k <= steps; ++k) {
        const double lead = double(k) * logged.step_s;
        apply_lead(logged, program, lead, m);
        const double a = block_agreement(logged, m.block, m.block_names);
        if (a > best_agreement + 1e-12) {
            best_agreement = a;
            best_lead = lead;
        }
    }
    return best_lead;
}

}  // namespace cutload::motion_io
