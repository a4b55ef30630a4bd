#include "motion_io/motion_io.hpp"

#include <nlohmann/json.hpp>

namespace cutload::motion_io {

nlohmann::json report_to_json(const IngestReport& r) {
    nlohmann::json channels = nlohmann::json::object();
    for (const auto& [name, c] : r.channels) {
        channels[name] = {{"samples", c.samples},
                          {"interval_s", {{"min", c.interval.min_s}, {"median", c.interval.median_s}, {"max", c.interval.max_s}}},
                          {"update_period_s", c.update_period_s},
                          {"stale_dropped", c.stale_dropped}};
    }
    nlohmann::json warnings = nlohmann::json::array();
    for (const auto& w : r.warnings) warnings.push_back({{"code", w.code}, {"count", w.count}, {"message", w.message}});
    return {{"file", r.file},
            {"format", r.format},
            {"duration_s", r.duration_s},
            {"sessions", r.sessions},
            {"blocks", r.blocks},
            {"channels", channels},
            {"feed_mm_min",
             {{"raw", {{"min", r.feed_raw_min_mm_min}, {"max", r.feed_raw_max_mm_min}}},
              {"repaired", {{"min", r.feed_repaired_min_mm_min}, {"max", r.feed_repaired_max_mm_min}}}}},
            {"first_position_mm", r.first_position_mm ? nlohmann::json(*r.first_position_mm) : nlohmann::json(nullptr)},
            {"warnings", warnings}};
}

}  // namespace cutload::motion_io
