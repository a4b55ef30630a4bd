#include "force_model/feed_optimizer.hpp"
#include "motion_io/hermite.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <stdexcept>

namespace cutload::force_model {
namespace {

constexpr int kQuantities = 5;
constexpr std::array<const char*, kQuantities> kQuantityNames{"force", "torque", "power", "chip", "bending"};

std::array<double, kQuantities> limits_of(const Limits& l) { return {l.force_N, l.torque_Nm, l.power_kW, l.chip_mm, l.bending_MPa}; }

// The limits of the blocks a tool cuts: its own over the run's.
std::array<double, kQuantities> tool_limits(const RunSpec& spec, int tool) {
    const NumberedTool* t = tool >= 0 ? find_tool(spec, tool) : nullptr;
    return limits_of(t ? limits_for(spec.limits, t->limits) : spec.limits);
}

std::array<double, kQuantities> values_of(const BlockSummary& b) {
    return {b.peak_force_N, b.peak_torque_Nm, b.peak_power_kW, b.max_chip_mm, b.max_bending_MPa};
}

bool feed_move(const motion_io::NcBlock& b) {
    return motion_io::block_moves(b) && b.motion != motion_io::NcMotion::Rapid;
}

// One name (N number) of the program whose feed the optimizer sets.
struct Unit {
    std::string name;
    std::vector<std::size_t> blocks;   // feed moves with this name
    std::array<double, kQuantities> lim{};   // of the tool of its first block
    double programmed_mm_min = 0;      // of the first one
    double scale = 1;                  // recommended / programmed
    struct Point {
        double feed_mm_min;
        std::array<double, kQuantities> values;
    };
    std::vector<Point> history;
    double best_feasible_scale = 0;    // largest scale seen at or below the target (0: none yet)
    bool cuts = false, done = false, at_limit = false;
    bool over_at_programmed = false;   // over the target at its programmed feed: never raised
    bool fixed = false;                // keeps its programmed feed (only_flagged, never_raise)
};

double ratio(const std::array<double, kQuantities>& v, const std::array<double, kQuantities>& lim, int* which = nullptr) {
    double r = 0;
    for (int k = 0; k < kQuantities; ++k)
        if (lim[k] > 0 && v[k] / lim[k] > r) {
            r = v[k] / lim[k];
            if (which) *which = k;
        }
    return r;
}

// The feed at which every limited quantity reaches aim x limit, from the unit's history: each
// quantity is affine in the feed (chip thickness h ~ feed; force, torque and power are K_c h b +
// K_e b), so two feeds determine it; with one, assume proportionality.
double next_feed(const Unit& u, const std::array<double, kQuantities>& lim, double aim) {
    const Unit::Point& last = u.history.back();
    const Unit::Point* prev = nullptr;
    for (auto it = u.history.rbegin() + 1; it != u.history.rend(); ++it)
        if (std::abs(it->feed_mm_min - last.feed_mm_min) > 0.5) {
            prev = &*it;
            break;
        }
    double feed = std::numeric_limits<double>::infinity();
    for (int k = 0; k < kQuantities; ++k) {
        if (!(lim[k] > 0) || !(last.values[k] > 0)) continue;
        double f = last.feed_mm_min * aim * lim[k] / last.values[k];
        if (prev) {
            const double slope = (last.values[k] - prev->values[k]) / (last.feed_mm_min - prev->feed_mm_min);
            if (slope > 1e-12) f = last.feed_mm_min + (aim * lim[k] - last.values[k]) / slope;
        }
        feed = std::min(feed, f);
    }
    return feed;
}

std::vector<std::string> flag_names(const BlockSummary* b) {
    std::vector<std::string> names;
    if (b)
        for (const FlagHit& f : b->flags) names.push_back(f.flag);
    std::sort(names.begin(), names.end());
    names.erase(std::unique(names.begin(), names.end()), names.end());
    return names;
}

}  // namespace

motion_io::MotionModel retime_motion(const motion_io::MotionModel& m, const std::vector<double>& speed_scale,
                                     const std::vector<double>& programmed_mm_min) {
    auto scale_of = [&](std::size_t i) {
        const std::int32_t b = m.block[i];
        const auto bi = static_cast<std::size_t>(b);
        const double k = b >= 0 && bi < speed_scale.size() ? speed_scale[bi] : 1.0;
        if (!(k > 0)) throw std::invalid_argument("retime_motion: speed scale must be > 0");
        const double f = b >= 0 && bi < programmed_mm_min.size() ? programmed_mm_min[bi] : 0.0;
        const double v = 60.0 * std::hypot(m.vx_mm_s[i], m.vy_mm_s[i], m.vz_mm_s[i]);
        if (!(f > 0) || v <= f) return k;
        return 1.0 + (k - 1.0) * (f / v) * (f / v);
    };
    motion_io::MotionModel out;
    out.step_s = m.step_s;
    out.block_names = m.block_names;
    const double h = m.step_s;
    for (std::size_t s = 0; s < m.session_start.size(); ++s) {
        const std::size_t a = m.session_start[s];
        const std::size_t b = s + 1 < m.session_start.size() ? m.session_start[s + 1] : m.size();
        if (b <= a) continue;
        std::vector<double> tau(b - a);
        tau[0] = m.t_s[a];
        for (std::size_t i = a; i + 1 < b; ++i) tau[i + 1 - a] = tau[i - a] + h / scale_of(i);
        out.session_start.push_back(out.size());
        std::size_t i = a;
        for (std::size_t j = 0;; ++j) {
            const double T = tau[0] + static_cast<double>(j) * h;
            if (T > tau.back() + 1e-12) break;
            while (i + 2 < b && tau[i + 1 - a] <= T) ++i;
            const bool single = b - a == 1;
            const std::size_t i1 = single ? i : i + 1;
            const double dt = single ? 1.0 : tau[i1 - a] - tau[i - a];
            const double u = single ? 0.0 : std::clamp((T - tau[i - a]) / dt, 0.0, 1.0);
            const double k0 = scale_of(i), k1 = scale_of(i1);
            // Cubic Hermite in the new time, slopes = old velocities x their block's scale.
            const std::vector<double>* pos[3] = {&m.x_mm, &m.y_mm, &m.z_mm};
            const std::vector<double>* vel[3] = {&m.vx_mm_s, &m.vy_mm_s, &m.vz_mm_s};
            std::vector<double>* opos[3] = {&out.x_mm, &out.y_mm, &out.z_mm};
            std::vector<double>* ovel[3] = {&out.vx_mm_s, &out.vy_mm_s, &out.vz_mm_s};
            for (int ax = 0; ax < 3; ++ax) {
                const motion_io::HermiteSegment seg{(*pos[ax])[i], (*vel[ax])[i] * k0, (*pos[ax])[i1],
                                                    (*vel[ax])[i1] * k1, dt};
                opos[ax]->push_back(seg.position(u));
                ovel[ax]->push_back(single ? 0.0 : seg.velocity(u));
            }
            const double rpm = m.spindle_rpm[i] + u * (m.spindle_rpm[i1] - m.spindle_rpm[i]);
            const double angle = j == 0 ? m.spindle_angle_deg[a] : out.spindle_angle_deg.back() + 6.0 * 0.5 * (out.spindle_rpm.back() + rpm) * h;
            out.t_s.push_back(T);
            out.spindle_rpm.push_back(rpm);
            out.spindle_angle_deg.push_back(angle);
            out.block.push_back(u < 1.0 ? m.block[i] : m.block[i1]);
            if (m.tool.size() == m.size()) out.tool.push_back(u < 1.0 ? m.tool[i] : m.tool[i1]);
        }
    }
    return out;
}

FeedOptimization optimize_feeds(const motion_io::NcProgram& program, const motion_io::MotionModel& actual,
                                const RunSpec& spec, const PredictOptions& predict_options,
                                const FeedOptimizerOptions& o) {
    auto any_limit = [](const std::array<double, kQuantities>& l) { return std::any_of(l.begin(), l.end(), [](double x) { return x > 0; }); };
    bool limited = any_limit(limits_of(spec.limits));
    for (const NumberedTool& t : spec.tools) limited = limited || any_limit(tool_limits(spec, t.number));
    if (!limited)
        throw SpecError("limits: none of force_N, torque_Nm, power_kW, chip_mm, bending_MPa is set; feeds cannot be optimised");
    if (!(o.target > 0 && o.target <= 1)) throw std::invalid_argument(fmt::format("target {}: must be in (0, 1]", o.target));
    const double max_feed = o.max_feed_mm_min > 0 ? o.max_feed_mm_min : 0.9 * spec.limits.rapid_feed_mm_min;
    if (!(o.min_feed_mm_min > 0 && o.min_feed_mm_min < max_feed))
        throw std::invalid_argument(fmt::format("feed range {}..{} mm/min is empty", o.min_feed_mm_min, max_feed));
    if (o.max_predictions < 2) throw std::invalid_argument("max_predictions must be >= 2");
    if (!(o.feed_step_mm_min >= 0)) throw std::invalid_argument("feed_step_mm_min must be >= 0");
    // The lowest feed a changed block may get: the minimum, raised to the step when there is one
    // (a shop's 50 mm/min step never states 10 mm/min).
    const double min_feed = o.feed_step_mm_min > 0
                                ? std::ceil(o.min_feed_mm_min / o.feed_step_mm_min - 1e-9) * o.feed_step_mm_min
                                : o.min_feed_mm_min;
    if (!(min_feed < max_feed))
        throw std::invalid_argument(fmt::format("feed range {}..{} mm/min is empty at a step of {} mm/min", min_feed, max_feed,
                                                o.feed_step_mm_min));

    std::vector<Unit> units;
    std::map<std::string, std::size_t> unit_of;
    for (std::size_t i = 0; i < program.blocks.size(); ++i) {
        const motion_io::NcBlock& b = program.blocks[i];
        if (!feed_move(b)) continue;
        auto [it, fresh] = unit_of.try_emplace(b.name, units.size());
        if (fresh) {
            Unit u;
            u.name = b.name;
            u.programmed_mm_min = b.feed_mm_min;
            u.lim = tool_limits(spec, b.tool);
            units.push_back(u);
        }
        units[it->second].blocks.push_back(i);
    }

    // A feed as the rewritten program will state it: clamped to the range, rounded down to the
    // step (not below the minimum), floored to what an F word can say.
    auto stated_feed = [&](const motion_io::NcBlock& b, double wanted_mm_min) {
        double f = std::clamp(wanted_mm_min, min_feed, max_feed);
        if (o.feed_step_mm_min > 0) f = std::max(min_feed, std::floor(f / o.feed_step_mm_min + 1e-9) * o.feed_step_mm_min);
        return motion_io::representable_feed_mm_min(b, f);
    };
    // The unit's effective scale follows its first block; a unit left alone keeps its feeds as
    // written.
    auto feeds_for = [&](std::vector<Unit>& us) {
        std::vector<double> feeds(program.blocks.size(), 0.0);
        for (Unit& u : us)
            for (std::size_t i : u.blocks) {
                const motion_io::NcBlock& b = program.blocks[i];
                feeds[i] = u.scale == 1.0 ? motion_io::representable_feed_mm_min(b, std::clamp(b.feed_mm_min, o.min_feed_mm_min, max_feed))
                                          : stated_feed(b, b.feed_mm_min * u.scale);
            }
        return feeds;
    };
    auto predict_at = [&](const std::vector<double>& feeds) {
        if (o.basis == FeedBasis::Commanded) {
            motion_io::CommandedOptions c = o.commanded;
            c.feed_mm_min = feeds;
            return predict(motion_io::commanded_motion(program, c), spec, predict_options);
        }
        std::vector<double> scale(actual.block_names.size(), 1.0), programmed(actual.block_names.size(), 0.0);
        for (std::size_t k = 0; k < actual.block_names.size(); ++k)
            if (const auto it = unit_of.find(actual.block_names[k]); it != unit_of.end()) {
                const Unit& u = units[it->second];
                scale[k] = feeds[u.blocks.front()] / u.programmed_mm_min;
                programmed[k] = u.programmed_mm_min;
            }
        return predict(retime_motion(actual, scale, programmed), spec, predict_options);
    };
    auto summary = [](const Prediction& p, const std::string& name) -> const BlockSummary* {
        for (const BlockSummary& b : p.blocks)
            if (b.block == name) return &b;
        return nullptr;
    };

    FeedOptimization r;
    // Aim a little below the target so the landing, after flooring and the model's small
    // non-linearity, stays at or under it.
    const double aim = o.target * (1 - 0.5 * o.tolerance);
    std::vector<double> feeds = feeds_for(units);
    for (;;) {
        Prediction p = predict_at(feeds);
        ++r.predictions;
        bool all_done = true;
        for (Unit& u : units) {
            const BlockSummary* s = summary(p, u.name);
            const std::array<double, kQuantities> v = s ? values_of(*s) : std::array<double, kQuantities>{};
            const double rr = ratio(v, u.lim);
            const double feed = feeds[u.blocks.front()];
            if (r.predictions == 1) {
                u.cuts = rr > 0;
                u.over_at_programmed = rr > o.target;
                u.fixed = (o.only_flagged && (!s || s->flags.empty())) || (o.never_raise && rr <= o.target);
            }
            if (!u.cuts || u.fixed) {
                u.done = true;
                continue;
            }
            u.history.push_back({feed, v});
            const double scale_now = feed / u.programmed_mm_min;
            if (rr <= o.target) u.best_feasible_scale = std::max(u.best_feasible_scale, scale_now);
            const bool at_max = feed >= stated_feed(program.blocks[u.blocks.front()], max_feed) - 1e-9;
            const bool at_min = feed <= min_feed + 1.0;   // within one F-word step
            u.at_limit = (at_max && rr <= o.target) || (at_min && rr > o.target);
            // One feed step may be wider than the tolerance: landing within a step of it is done.
            const double tol = std::max(o.tolerance, o.feed_step_mm_min / std::max(feed, 1.0));
            u.done = (rr <= o.target && rr >= o.target * (1 - tol)) || u.at_limit;
            all_done = all_done && u.done;
        }
        if (r.predictions == 1) r.before = std::move(p);
        else r.after = std::move(p);
        if (all_done) break;
        if (r.predictions + 1 >= o.max_predictions) {
            // Last prediction: the best feed seen at or below the target (lower when none was).
            for (Unit& u : units)
                if (u.cuts && !u.done) u.scale = u.best_feasible_scale > 0 ? u.best_feasible_scale : u.scale * 0.8;
            feeds = feeds_for(units);
            r.after = predict_at(feeds);
            ++r.predictions;
            break;
        }
        for (Unit& u : units)
            if (u.cuts && !u.done) {
                // At most 4x per step: far from the current feed the affine model is extrapolated
                // (below the minimum chip thickness a block stops cutting at all).
                const double now = u.history.back().feed_mm_min;
                double f = std::clamp(next_feed(u, u.lim, aim), now / 4, now * 4);
                // A block's load also depends on its neighbours' feeds (what they leave, how the
                // machine enters it), so its own history can point upwards even when it is over
                // the target: a block over it as programmed is only ever slowed.
                if (u.over_at_programmed || o.never_raise) f = std::min(f, u.programmed_mm_min);
                u.scale = std::clamp(f, min_feed, max_feed) / u.programmed_mm_min;
            }
        feeds = feeds_for(units);
    }
    if (r.predictions == 1) r.after = predict_at(feeds), ++r.predictions;   // nothing to change: show it anyway
    // Tooth-phase jitter of block peaks (a few %) can carry a block just over the target: lower
    // those blocks until none is over, at most three more predictions.
    for (int round = 0; round < 3; ++round) {
        bool over = false;
        for (Unit& u : units) {
            if (!u.cuts || u.fixed) continue;
            const BlockSummary* s = summary(r.after, u.name);
            const double rr = s ? ratio(values_of(*s), u.lim) : 0.0;
            if (rr > o.target && feeds[u.blocks.front()] > min_feed + 1.0) {
                u.scale *= o.target / rr * (1 - 0.5 * o.tolerance);
                over = true;
            }
        }
        if (!over) break;
        feeds = feeds_for(units);
        r.after = predict_at(feeds);
        ++r.predictions;
    }

    r.feed_mm_min = feeds;
    r.target_met = true;
    for (const Unit& u : units) {
        if (!u.cuts) continue;
        BlockFeed bf;
        bf.block = u.name;
        bf.programmed_feed_mm_min = u.programmed_mm_min;
        bf.recommended_feed_mm_min = feeds[u.blocks.front()];
        int which = 0;
        const BlockSummary* before = summary(r.before, u.name);
        const BlockSummary* after = summary(r.after, u.name);
        if (before) bf.ratio_before = ratio(values_of(*before), u.lim);
        if (after) bf.ratio_after = ratio(values_of(*after), u.lim, &which);
        bf.binding = kQuantityNames[static_cast<std::size_t>(which)];
        bf.at_feed_limit = u.at_limit;
        bf.flags_before = flag_names(before);
        bf.flags_after = flag_names(after);
        const double tol = std::max(o.tolerance, o.feed_step_mm_min / std::max(bf.recommended_feed_mm_min, 1.0));
        // A block left alone by choice (only_flagged, never_raise) has no target to meet, unless
        // it is over it.
        const bool close = u.fixed || bf.ratio_after >= o.target * (1 - tol) || bf.at_feed_limit;
        if (bf.ratio_after > o.target + 1e-9 || !close) r.target_met = false;
        r.blocks.push_back(bf);
    }
    for (const BlockSummary& b : r.after.blocks)
        if (const double rr = ratio(values_of(b), tool_limits(spec, b.tool)); rr > r.max_ratio_after) {
            r.max_ratio_after = rr;
            r.max_ratio_block = b.block;
        }
    return r;
}

}  // namespace cutload::force_model
