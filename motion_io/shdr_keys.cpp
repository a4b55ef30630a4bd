// The SHDR key map: which data items feed which channel (docs/formats.md, "Key map").
#include "motion_io/shdr.hpp"
#include "pipeline.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <fstream>
#include <map>

namespace cutload::motion_io {

ShdrKeyMap default_shdr_key_map() {
    ShdrKeyMap m;
    m.position = {"path_pos", "p1LPathPos", "Lp1LPathPos", "PathPos"};
    m.x = {"X1actw", "Xact", "Xabs", "Xpos", "X1actm"};
    m.y = {"Y1actw", "YI1actw", "Yact", "Yabs", "Ypos", "Y1actm", "YI1actm"};
    m.z = {"Z1actw", "Zact", "Zabs", "Zpos", "Z1actm"};
    m.feed = {"p1Fact", "path_feedrate", "Fact", "Frt"};
    // The milling (tool) spindle first: on Okuma multitasking controls S6 turns the cutter while
    // S1/S2 turn the workpiece; a plain machining centre only has S1.
    m.spindle = {"S6speed", "S1speed", "Sspeed", "spindle_speed", "Srpm"};
    m.block = {"p1BlockNumber", "line", "block", "p1linenumber"};
    return m;
}

ShdrKeyMap load_shdr_key_map(const std::string& path) {
    ShdrKeyMap m = default_shdr_key_map();
    if (path.empty()) return m;
    std::ifstream in(path);
    if (!in) throw IngestError(fmt::format("{}: cannot open SHDR map file", path));
    nlohmann::json j;
    try {
        in >> j;
    } catch (const nlohmann::json::parse_error& e) {
        throw IngestError(fmt::format("{}: not valid JSON: {}", path, e.what()));
    }
    if (!j.is_object()) throw IngestError(fmt::format("{}: expected a JSON object mapping channels to keys", path));
    const std::map<std::string, std::vector<std::string>*> lists{
        {"position", &m.position}, {"x", &m.x}, {"y", &m.y}, {"z", &m.z},
        {"feed", &m.feed}, {"spindle", &m.spindle}, {"block", &m.block}};
    for (const auto& [key, value] : j.items()) {
        if (key == "units") {
            if (!value.is_object()) throw IngestError(fmt::format("{}: key 'units': expected an object", path));
            for (const auto& [u, v] : value.items()) {
                if (!v.is_string()) throw IngestError(fmt::format("{}: key 'units.{}': expected a string", path, u));
                std::string* dst = u == "length" ? &m.length_unit : u == "feed" ? &m.feed_unit
                                 : u == "spindle" ? &m.spindle_unit : nullptr;
                if (!dst) throw IngestError(fmt::format("{}: key 'units.{}': expected length, feed or spindle", path, u));
                *dst = v.get<std::string>();
            }
            continue;
        }
        const auto it = lists.find(key);
        if (it == lists.end())
            throw IngestError(fmt::format("{}: unknown key '{}' (expected position, x, y, z, feed, spindle, block, units)",
                                          path, key));
        std::vector<std::string> keys;
        if (value.is_string()) {
            keys.push_back(value.get<std::string>());
        } else if (value.is_array()) {
            for (const auto& k : value) {
                if (!k.is_string()) throw IngestError(fmt::format("{}: key '{}': expected strings", path, key));
                keys.push_back(k.get<std::string>());
            }
        } else {
            throw IngestError(fmt::format("{}: key '{}': expected a data-item key or a list of keys", path, key));
        }
        *it->second = std::move(keys);
    }
    return m;
}

ShdrUnitFactors shdr_unit_factors(const ShdrKeyMap& map, const ReadOptions& opt) {
    ShdrUnitFactors f;
    f.length_mm = detail::length_factor_mm(opt.length_unit.value_or(map.length_unit));
    f.feed_mm_min = detail::feed_factor_mm_min(
        opt.feed_unit.value_or(opt.length_unit && !opt.feed_unit ? *opt.length_unit + "/s" : map.feed_unit));
    f.spindle_rpm = detail::speed_factor_rpm(map.spindle_unit);
    return f;
}

}  // namespace cutload::motion_io
