#include "force_model/logged_commanded.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

namespace cutload::force_model {
namespace {

double speed_mm_min(const motion_io::MotionModel& m, std::size_t i) {
    return 60.0 * std::hypot(m.vx_mm_s[i], m.vy_mm_s[i], m.vz_mm_s[i]);
}

std::size_t session_end(const motion_io::MotionModel& m, std::size_t k) {
    return k + 1 < m.session_start.size() ? m.session_start[k + 1] : m.size();
}

const BlockSummary* summary_of(const Prediction& p, const std::string& name) {
    const auto it = std::find_if(p.blocks.begin(), p.blocks.end(), [&](const BlockSummary& b) { return b.block == name; });
    return it == p.blocks.end() ? nullptr : &*it;
}

// Distance from each actual sample to the commanded position at its time (NaN outside the
// commanded motion's span of that session, or when the sessions do not pair up).
std::vector<double> deviations_mm(const motion_io::MotionModel& a, const motion_io::MotionModel& c) {
    std::vector<double> d(a.size(), std::numeric_limits<double>::quiet_NaN());
    if (a.session_start.size() != c.session_start.size()) return d;
    for (std::size_t k = 0; k < a.session_start.size(); ++k) {
        const std::size_t c0 = c.session_start[k], c1 = session_end(c, k);
        if (c1 < c0 + 2) continue;
        for (std::size_t i = a.session_start[k]; i < session_end(a, k); ++i) {
            const double t = a.t_s[i];
            if (t < c.t_s[c0] || t > c.t_s[c1 - 1]) continue;
            const auto it = std::upper_bound(c.t_s.begin() + static_cast<std::ptrdiff_t>(c0),
                                             c.t_s.begin() + static_cast<std::ptrdiff_t>(c1), t);
            const std::size_t j = std::min(static_cast<std::size_t>(it - c.t_s.begin()), c1 - 1) - 1;
            const motion_io::MotionState s = motion_io::sample_between(c, j, t);
            d[i] = std::hypot(a.x_mm[i] - s.pos_mm[0], a.y_mm[i] - s.pos_mm[1], a.z_mm[i] - s.pos_mm[2]);
        }
    }
    return d;
}

}  // namespace

std::vector<BlockComparison> compare_logged_commanded(const motion_io::MotionModel& actual,
                                                      const motion_io::MotionModel& commanded,
                                                      const Prediction& commanded_prediction,
                                                      const Prediction& actual_prediction) {
    std::vector<BlockComparison> rows;
    std::map<std::string, std::size_t> row_of;
    struct Sums {
        double commanded_feed = 0, actual_feed = 0, deviation = 0;
        std::size_t commanded_n = 0, deviation_n = 0;
    };
    std::vector<Sums> sums;
    auto row = [&](const std::string& name) -> std::size_t {
        auto [it, fresh] = row_of.try_emplace(name, rows.size());
        if (fresh) {
            rows.emplace_back().block = name;
            sums.emplace_back();
        }
        return it->second;
    };
    const std::vector<double> dev = deviations_mm(actual, commanded);
    for (std::size_t i = 0; i < actual.size(); ++i) {
        if (actual.block[i] < 0) continue;
        const std::size_t k = row(actual.block_names[static_cast<std::size_t>(actual.block[i])]);
        BlockComparison& r = rows[k];
        const double feed = speed_mm_min(actual, i);
        r.actual_min_feed_mm_min = r.samples == 0 ? feed : std::min(r.actual_min_feed_mm_min, feed);
        r.actual_max_feed_mm_min = std::max(r.actual_max_feed_mm_min, feed);
        sums[k].actual_feed += feed;
        ++r.samples;
        if (!std::isnan(dev[i])) {
            r.max_deviation_mm = std::max(r.max_deviation_mm, dev[i]);
            sums[k].deviation += dev[i];
            ++sums[k].deviation_n;
        }
    }
    for (std::size_t i = 0; i < commanded.size(); ++i) {
        if (commanded.block[i] < 0) continue;
        const std::size_t k = row(commanded.block_names[static_cast<std::size_t>(commanded.block[i])]);
        sums[k].commanded_feed += speed_mm_min(commanded, i);
        ++sums[k].commanded_n;
    }
    for (std::size_t k = 0; k < rows.size(); ++k) {
        BlockComparison& r = rows[k];
        const Sums& s = sums[k];
        r.actual_duration_s = static_cast<double>(r.samples) * actual.step_s;
        r.commanded_duration_s = static_cast<double>(s.commanded_n) * commanded.step_s;
        if (r.samples) r.actual_mean_feed_mm_min = s.actual_feed / static_cast<double>(r.samples);
        if (s.commanded_n) r.programmed_feed_mm_min = s.commanded_feed / static_cast<double>(s.commanded_n);
        if (s.deviation_n) r.mean_deviation_mm = s.deviation / static_cast<double>(s.deviation_n);
        if (r.programmed_feed_mm_min > 0 && r.samples) {
            r.feed_deficit_pct = std::max(0.0, 100.0 * (1.0 - r.actual_min_feed_mm_min / r.programmed_feed_mm_min));
            r.feed_surge_pct = std::max(0.0, 100.0 * (r.actual_max_feed_mm_min / r.programmed_feed_mm_min - 1.0));
        }
        if (const BlockSummary* b = summary_of(commanded_prediction, r.block)) r.commanded_peak_force_N = b->peak_force_N;
        if (const BlockSummary* b = summary_of(actual_prediction, r.block)) r.actual_peak_force_N = b->peak_force_N;
        r.force_difference_N = r.actual_peak_force_N - r.commanded_peak_force_N;
        r.force_difference_pct = r.commanded_peak_force_N > 0 ? 100.0 * r.force_difference_N / r.commanded_peak_force_N : 0.0;
    }
    return rows;
}

}  // namespace cutload::force_model
