#include "motion_io/motion_io.hpp"

#include "textio/text.hpp"

#include <nlohmann/json.hpp>

namespace cutload::motion_io {

namespace {

nlohmann::json warnings_json(const std::vector<IngestWarning>& ws) {
    nlohmann::json warnings = nlohmann::json::array();
    for (const auto& w : ws) warnings.push_back({{"code", w.code}, {"count", w.count}, {"message", w.message}});
    return warnings;
}

}  // namespace

nlohmann::json report_to_json(const IngestReport& r) {
    nlohmann::json channels = nlohmann::json::object();
    for (const auto& [name, c] : r.channels) {
        channels[name] = {{"samples", c.samples},
                          {"interval_s", {{"min", c.interval.min_s}, {"median", c.interval.median_s}, {"max", c.interval.max_s}}},
                          {"update_period_s", c.update_period_s},
                          {"stale_dropped", c.stale_dropped}};
    }
    // The file name is the operating system's bytes, not necessarily UTF-8.
    return {{"file", textio::printable(r.file)},
            {"format", r.format},
            {"duration_s", r.duration_s},
            {"sessions", r.sessions},
            {"blocks", r.blocks},
            {"channels", channels},
            {"feed_mm_min",
             {{"raw", {{"min", r.feed_raw_min_mm_min}, {"max", r.feed_raw_max_mm_min}}},
              {"repaired", {{"min", r.feed_repaired_min_mm_min}, {"max", r.feed_repaired_max_mm_min}}}}},
            {"first_position_mm", r.first_position_mm ? nlohmann::json(*r.first_position_mm) : nlohmann::json(nullptr)},
            {"position_step_mm", r.position_step_mm ? nlohmann::json(*r.position_step_mm) : nlohmann::json(nullptr)},
            {"spindle_max_rpm", r.spindle_max_rpm},
            {"commanded_positions", r.commanded_positions},
            {"rotary_axes", r.rotary_axes},
            {"warnings", warnings_json(r.warnings)}};
}

nlohmann::json to_json(const SamplingCheck& c) {
    return {{"coarse", c.coarse()},
            {"sample_period_s", c.sample_period_s},
            {"position_step_mm", c.position_step_mm ? nlohmann::json(*c.position_step_mm) : nlohmann::json(nullptr)},
            {"spindle_max_rpm", c.spindle_max_rpm},
            {"tooth_period_s", c.tooth_period_s},
            {"position_quantized", c.position_quantized},
            {"sampling_coarse", c.sampling_coarse},
            {"warnings", warnings_json(c.warnings)}};
}

}  // namespace cutload::motion_io
