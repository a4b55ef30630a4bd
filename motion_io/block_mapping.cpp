#include "motion_io/block_mapping.hpp"

#include "motion_io/commanded.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <optional>
#include <stdexcept>
#include <unordered_map>

namespace cutload::motion_io {
namespace {

// Every this many samples a long loop reads the cancel flag (a load, negligible beside a sample's work).
constexpr std::size_t kCancelEvery = 4096;

void check_cancel(const BlockMappingOptions& opt, std::size_t i = 0) {
    if (i % kCancelEvery == 0 && opt.cancel && opt.cancel->load()) throw MappingCancelled();
}


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

// Where the program's tool changes come: the arc length and the point of the path there.
struct ToolChangeAt {
    double s_mm;
    double p[3];
};

std::vector<ToolChangeAt> tool_change_positions(const NcProgram& program) {
    std::vector<ToolChangeAt> out;
    double s = 0;
    const NcBlock* last_move = nullptr;
    for (const NcBlock& b : program.blocks) {
        if (b.tool_change) {
            ToolChangeAt t{s, {b.start_mm[0], b.start_mm[1], b.start_mm[2]}};
            if (last_move) std::copy(last_move->end_mm.begin(), last_move->end_mm.end(), t.p);
            out.push_back(t);
        }
        if (block_moves(b)) {
            s += block_length_mm(b);
            last_move = &b;
        }
    }
    return out;
}

// Geometric matching only (program_block, distance_mm, path_mm).
//
// A tool change sends the machine off the path (to the change position) and back, often over
// the start of the next move: the tracker passes a tool-change block only once the log has gone
// farther than twice max_distance_mm from where the change comes, or rested there for
// kToolChangeRest_s, so that the way out is not mistaken for the next block.
void match_geometry(const MotionModel& motion, const std::vector<Chord>& chords, const std::vector<ToolChangeAt>& tool_changes,
                    const BlockMappingOptions& opt, BlockMapping& out) {
    constexpr double kToolChangeRest_s = 0.5, kAtBarrier_mm = 0.5;
    const std::size_t n = motion.size();
    out.program_block.assign(n, -1);
    out.distance_mm.assign(n, std::numeric_limits<double>::quiet_NaN());
    out.path_mm.assign(n, std::numeric_limits<double>::quiet_NaN());
    if (chords.empty()) return;
    std::size_t session = 0, barrier = 0;
    bool barrier_open = false;
    double rest_at_barrier_s = 0;
    double s_prev = 0, travel_since_search = 0;
    double prev[3] = {0, 0, 0};
    const double inf = std::numeric_limits<double>::infinity();
    for (std::size_t i = 0; i < n; ++i) {
        check_cancel(opt, i);
        const double p[3] = {motion.x_mm[i], motion.y_mm[i], motion.z_mm[i]};
        const bool session_begins = session < motion.session_start.size() && motion.session_start[session] == i;
        double travel = 0;
        if (session_begins) {
            ++session;
            s_prev = 0;   // a new recording may run the program from its start again
            travel_since_search = inf;
            barrier = 0;
            barrier_open = false;
            rest_at_barrier_s = 0;
        } else {
            travel = std::hypot(p[0] - prev[0], p[1] - prev[1], p[2] - prev[2]);
        }
        std::copy(p, p + 3, prev);
        const bool blocked = barrier < tool_changes.size() && !barrier_open;
        const double s_limit = blocked ? tool_changes[barrier].s_mm : inf;
        auto allowed = [&](const Chord& c) { return c.s0_mm < s_limit - 1e-9; };
        const double s_hi = std::min(s_prev + 3 * travel + opt.slack_mm, s_limit);
        Match best;
        for (std::size_t c = chord_at(chords, s_prev); c < chords.size() && chords[c].s0_mm <= s_hi && allowed(chords[c]); ++c)
            consider(chords[c], c, p, s_prev, s_hi, best);
        travel_since_search += travel;
        if (best.dist_mm > opt.max_distance_mm && travel_since_search >= 1.0) {
            // Lost (the log left the program, or started elsewhere): look ahead along the whole
            // rest of the program, at most once per mm of travel.
            travel_since_search = 0;
            for (std::size_t c = chord_at(chords, s_prev); c < chords.size() && allowed(chords[c]); ++c)
                consider(chords[c], c, p, s_prev, s_limit, best);
        }
        const bool matched = best.dist_mm <= opt.max_distance_mm;
        if (blocked && s_prev >= tool_changes[barrier].s_mm - kAtBarrier_mm) {
            const double* at = tool_changes[barrier].p;
            if (std::hypot(p[0] - at[0], p[1] - at[1], p[2] - at[2]) > 2 * opt.max_distance_mm) barrier_open = true;
            if (60.0 * std::hypot(motion.vx_mm_s[i], motion.vy_mm_s[i], motion.vz_mm_s[i]) < opt.rest_speed_mm_min)
                rest_at_barrier_s += motion.step_s;
            if (rest_at_barrier_s >= kToolChangeRest_s) barrier_open = true;
        }
        if (!matched) continue;
        s_prev = best.s_mm;
        while (barrier < tool_changes.size() && s_prev > tool_changes[barrier].s_mm + 1e-9) {
            ++barrier;   // passed: the next one must be reached and left again
            barrier_open = false;
            rest_at_barrier_s = 0;
        }
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

double speed_mm_min(const MotionModel& m, std::size_t i) { return 60.0 * std::hypot(m.vx_mm_s[i], m.vy_mm_s[i], m.vz_mm_s[i]); }

// The cutting moves (G01/G02/G03) as short pieces in a uniform grid, for "is this sample near
// any cutting move" in about constant time. Pieces are at most one cell long, so a point within
// `reach` of a piece lies within reach + cell/2 of its midpoint: two cells around suffice.
class CutIndex {
public:
    CutIndex(const std::vector<Chord>& chords, const NcProgram& program, double reach_mm) : reach_(reach_mm) {
        // Cells no smaller than the reach (two around then suffice), 1 mm, or a millionth of
        // the cutting path (bounded memory for any program).
        double cut_mm = 0;
        for (const Chord& c : chords)
            if (program.blocks[static_cast<std::size_t>(c.block)].motion != NcMotion::Rapid) cut_mm += c.len_mm;
        cell_ = std::max({reach_mm, 1.0, cut_mm / 1e6});
        for (const Chord& c : chords) {
            if (program.blocks[static_cast<std::size_t>(c.block)].motion == NcMotion::Rapid) continue;
            const int pieces = std::max(1, static_cast<int>(std::ceil(c.len_mm / cell_)));
            for (int k = 0; k < pieces; ++k) {
                Piece pc;
                for (int a = 0; a < 3; ++a) {
                    pc.p0[a] = c.p0[a] + c.d[a] * k / pieces;
                    pc.d[a] = c.d[a] / pieces;
                }
                double mid[3];
                for (int a = 0; a < 3; ++a) mid[a] = pc.p0[a] + 0.5 * pc.d[a];
                cells_[key(cell_of(mid[0]), cell_of(mid[1]), cell_of(mid[2]))].push_back(pieces_.size());
                pieces_.push_back(pc);
            }
        }
    }

    bool near(const double p[3]) const {
        const std::int64_t cx = cell_of(p[0]), cy = cell_of(p[1]), cz = cell_of(p[2]);
        for (std::int64_t dx = -2; dx <= 2; ++dx)
            for (std::int64_t dy = -2; dy <= 2; ++dy)
                for (std::int64_t dz = -2; dz <= 2; ++dz) {
                    const auto it = cells_.find(key(cx + dx, cy + dy, cz + dz));
                    if (it == cells_.end()) continue;
                    for (std::size_t k : it->second)
                        if (distance(pieces_[k], p) <= reach_) return true;
                }
        return false;
    }

private:
    struct Piece {
        double p0[3], d[3];
    };
    std::int64_t cell_of(double v) const { return static_cast<std::int64_t>(std::floor(v / cell_)); }
    static std::uint64_t key(std::int64_t x, std::int64_t y, std::int64_t z) {
        // 21 bits per axis: positions are bounded (NcLimits), cells at least a few mm.
        const auto m = [](std::int64_t v) { return static_cast<std::uint64_t>(v + (1 << 20)) & 0x1FFFFFu; };
        return (m(x) << 42) | (m(y) << 21) | m(z);
    }
    static double distance(const Piece& c, const double p[3]) {
        const double dd = c.d[0] * c.d[0] + c.d[1] * c.d[1] + c.d[2] * c.d[2];
        double u = dd > 0 ? ((p[0] - c.p0[0]) * c.d[0] + (p[1] - c.p0[1]) * c.d[1] + (p[2] - c.p0[2]) * c.d[2]) / dd : 0.0;
        u = std::clamp(u, 0.0, 1.0);
        return std::hypot(p[0] - c.p0[0] - u * c.d[0], p[1] - c.p0[1] - u * c.d[1], p[2] - c.p0[2] - u * c.d[2]);
    }
    double reach_, cell_ = 1;
    std::vector<Piece> pieces_;
    std::unordered_map<std::uint64_t, std::vector<std::size_t>> cells_;
};

// Blocks that take time without moving: a dwell, a tool change.
bool stationary(const NcBlock& b) { return (b.motion == NcMotion::Dwell && b.dwell_s > 0) || b.tool_change; }

// A stretch of samples at rest or off the path lies between the moves before and after it; a
// dwell or a tool change of the program between those moves is what the machine was doing: the
// CNC's block counter names it for the stretch. A tool change takes the stretch up to its last
// sample at rest (the machine went to the change position and waited); the move back to the
// work is the next block's. A dwell takes the samples at rest. `tool_change` marks the samples of
// stretches given to a tool change.
void attribute_stationary(const MotionModel& motion, const NcProgram& program, const BlockMappingOptions& opt,
                          BlockMapping& out, std::vector<std::uint8_t>& tool_change) {
    const std::size_t n = motion.size();
    tool_change.assign(n, 0);
    if (std::none_of(program.blocks.begin(), program.blocks.end(), stationary)) return;
    std::map<std::string, std::int32_t> index;
    for (std::size_t k = 0; k < out.block_names.size(); ++k) index[out.block_names[k]] = static_cast<std::int32_t>(k);
    auto at_rest = [&](std::size_t i) { return speed_mm_min(motion, i) < opt.rest_speed_mm_min; };
    auto candidate = [&](std::size_t i) { return out.program_block[i] < 0 || at_rest(i); };
    const auto nblocks = static_cast<std::int32_t>(program.blocks.size());
    for (std::size_t session = 0; session < std::max<std::size_t>(1, motion.session_start.size()); ++session) {
        const std::size_t s0 = session < motion.session_start.size() ? motion.session_start[session] : 0;
        const std::size_t s1 = session + 1 < motion.session_start.size() ? motion.session_start[session + 1] : n;
        std::int32_t before = -1;
        for (std::size_t i = s0; i < s1;) {
            if (!candidate(i)) {
                before = out.program_block[i];
                ++i;
                continue;
            }
            std::size_t j = i;
            while (j < s1 && candidate(j)) ++j;
            const std::int32_t after = j < s1 ? out.program_block[j] : nblocks;
            // The last tool change between the two moves, else the longest dwell.
            std::int32_t chosen = -1;
            for (std::int32_t k = before + 1; k < after; ++k) {
                const NcBlock& b = program.blocks[static_cast<std::size_t>(k)];
                if (b.tool_change) chosen = k;
                else if (b.motion == NcMotion::Dwell && b.dwell_s > 0 &&
                         (chosen < 0 || (!program.blocks[static_cast<std::size_t>(chosen)].tool_change &&
                                         b.dwell_s > program.blocks[static_cast<std::size_t>(chosen)].dwell_s)))
                    chosen = k;
            }
            if (chosen >= 0) {
                const std::int32_t name = index.at(program.blocks[static_cast<std::size_t>(chosen)].name);
                std::size_t first_rest = j, last_rest = j;
                for (std::size_t k = i; k < j; ++k)
                    if (at_rest(k)) {
                        if (first_rest == j) first_rest = k;
                        last_rest = k;
                    }
                if (program.blocks[static_cast<std::size_t>(chosen)].tool_change) {
                    const std::size_t until = last_rest < j ? last_rest + 1 : j;
                    for (std::size_t k = i; k < j; ++k) {
                        tool_change[k] = 1;
                        out.block[k] = k < until ? name : (j < s1 ? out.block[j] : out.block[k]);
                    }
                } else if (first_rest < j) {
                    for (std::size_t k = first_rest; k <= last_rest; ++k) out.block[k] = name;
                }
            }
            i = j;
        }
    }
}

void fill_quality(const MotionModel& motion, const NcProgram& program, const std::vector<Chord>& chords,
                  const BlockMappingOptions& opt, const std::vector<std::uint8_t>& tool_change, BlockMapping& out) {
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

    // Unmatched samples that do not count against the match.
    double fastest_cut_mm_min = 0;
    for (const NcBlock& b : program.blocks)
        if (block_moves(b) && b.motion != NcMotion::Rapid) fastest_cut_mm_min = std::max(fastest_cut_mm_min, b.feed_mm_min);
    std::optional<CutIndex> cuts;
    for (std::size_t i = 0; i < motion.size(); ++i) {
        check_cancel(opt, i);
        if (out.program_block[i] >= 0) continue;
        const double v = speed_mm_min(motion, i);
        if (tool_change[i]) {
            ++q.excluded_tool_change;
        } else if (v < opt.rest_speed_mm_min) {
            ++q.excluded_at_rest;
        } else if (v > fastest_cut_mm_min && v > opt.rapid_fraction * opt.rapid_mm_min) {
            if (!cuts) cuts.emplace(chords, program, opt.away_mm);
            const double p[3] = {motion.x_mm[i], motion.y_mm[i], motion.z_mm[i]};
            if (!cuts->near(p)) ++q.excluded_away;
        }
    }
    const std::size_t excluded = q.excluded_tool_change + q.excluded_at_rest + q.excluded_away;
    q.excluded_fraction = q.samples ? double(excluded) / double(q.samples) : 0.0;
    q.counted_matched_fraction = q.samples > excluded ? double(q.matched) / double(q.samples - excluded) : 0.0;
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
    if (!(opt.max_distance_mm > 0) || opt.lead_s < 0 || opt.slack_mm < 0 || !(opt.away_mm > 0) || opt.rest_speed_mm_min < 0)
        throw std::invalid_argument("block mapping: max distance and away distance must be > 0, lead, slack and rest speed >= 0");
    const std::vector<Chord> chords = program_chords(program);
    BlockMapping out;
    out.block_names = program_block_names(program);
    match_geometry(motion, chords, tool_change_positions(program), opt, out);
    check_cancel(opt);
    apply_lead(motion, program, opt.lead_s, out);
    std::vector<std::uint8_t> tool_change;
    attribute_stationary(motion, program, opt, out, tool_change);
    check_cancel(opt);
    fill_quality(motion, program, chords, opt, tool_change, out);
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
    match_geometry(logged, chords, tool_change_positions(program), o, m);
    std::vector<std::uint8_t> tool_change;
    double best_lead = 0, best_agreement = -1;
    const auto steps = static_cast<long>(std::floor(max_lead_s / logged.step_s + 1e-9));
    for (long k = 0; k <= steps; ++k) {
        check_cancel(o);   // each lead is a pass over the whole log
        const double lead = double(k) * logged.step_s;
        apply_lead(logged, program, lead, m);
        attribute_stationary(logged, program, o, m, tool_change);
        const double a = block_agreement(logged, m.block, m.block_names);
        if (a > best_agreement + 1e-12) {
            best_agreement = a;
            best_lead = lead;
        }
    }
    return best_lead;
}

}  // namespace cutload::motion_io
