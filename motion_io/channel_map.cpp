// Channel maps: built-in defaults per format, JSON map files and the bundled presets.
#include "channel_map.hpp"

#include "textio/json.hpp"
#include "textio/text.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <filesystem>
#include <map>

namespace cutload::motion_io::detail {

// Generated at configure time from data/maps/*.json (motion_io/CMakeLists.txt).
extern const std::map<std::string, std::string>& bundled_map_presets();

namespace {

constexpr std::array<const char*, kMapChannels> kKeys{
    "position", "x", "y", "z", "x_cmd", "y_cmd", "z_cmd", "a", "b", "c",
    "feed", "spindle", "block", "tool", "t", "t_pos", "t_feed", "t_spindle"};

void set(ChannelMap& m, MapChannel c, std::vector<std::string> v) { m.candidates[static_cast<int>(c)] = std::move(v); }

ChannelMap csv_defaults() {
    ChannelMap m;
    // CSV columns are matched case-insensitively by their name without the unit.
    for (int c = 1; c < kMapChannels; ++c) m.candidates[c] = {kKeys[c]};
    return m;
}

ChannelMap shdr_defaults() {
    ChannelMap m;
    using C = MapChannel;
    set(m, C::Position, {"path_pos", "p1LPathPos", "Lp1LPathPos", "PathPos"});
    set(m, C::X, {"X1actw", "Xact", "Xabs", "Xpos", "X1actm"});
    set(m, C::Y, {"Y1actw", "YI1actw", "Yact", "Yabs", "Ypos", "Y1actm", "YI1actm"});
    set(m, C::Z, {"Z1actw", "Zact", "Zabs", "Zpos", "Z1actm"});
    set(m, C::XCmd, {"Xcom", "Xcmd", "X1cmdw"});
    set(m, C::YCmd, {"Ycom", "Ycmd", "Y1cmdw"});
    set(m, C::ZCmd, {"Zcom", "Zcmd", "Z1cmdw"});
    // Rotary axes (docs/five_axis.md, section 2.1): machine-coordinate items (*actm) before the
    // generic names and work-coordinate ones (*actw, which include a work offset), since
    // kinematics needs the axes' own positions. Okuma names the main spindle's C axis C3.
    set(m, C::A, {"A1actm", "Aact", "Aabs", "Apos", "A1actw"});
    set(m, C::B, {"B1actm", "Bact", "Babs", "Bpos", "B1actw"});
    set(m, C::C, {"C1actm", "C3actm", "Cact", "Cabs", "Cpos", "C1actw", "C3actw"});
    set(m, C::Feed, {"p1Fact", "path_feedrate", "Fact", "Frt"});
    // The milling (tool) spindle first: on Okuma multitasking controls S6 turns the cutter while
    // S1/S2 turn the workpiece; a plain machining centre only has S1.
    set(m, C::Spindle, {"S6speed", "S1speed", "Sspeed", "spindle_speed", "Srpm"});
    set(m, C::Block, {"p1BlockNumber", "line", "block", "p1linenumber"});
    return m;
}

// Keys a format cannot use are errors, not silently ignored: a map written for the other format
// would otherwise read as if it applied.
void check_applies(const std::string& key, Format format, const std::string& origin) {
    static const std::vector<std::string> csv_only{"tool", "t", "t_pos", "t_feed", "t_spindle", "sample_period_ms",
                                                   "units.time"};
    if (format == Format::Shdr && std::find(csv_only.begin(), csv_only.end(), key) != csv_only.end())
        throw IngestError(fmt::format("{}: key '{}' applies to CSV logs only (SHDR lines carry their own time stamps; "
                                      "the tool is not read from SHDR)", origin, key));
    if (format != Format::Shdr && key == "position")
        throw IngestError(fmt::format("{}: key 'position' is an SHDR 3-D path position; a CSV log names its axis "
                                      "columns with x, y, z", origin));
}

// The map document named by `spec`: a JSON file, or a bundled preset.
nlohmann::json read_map(const std::string& spec, std::string& origin) {
    std::error_code ec;
    try {
        if (std::filesystem::is_regular_file(spec, ec)) {
            origin = spec;
            return textio::read_json_file(spec, "map file");
        }
        const auto& presets = bundled_map_presets();
        if (const auto it = presets.find(spec); it != presets.end()) {
            origin = "map preset " + spec;
            return textio::parse_json(it->second, origin);
        }
    } catch (const textio::TextError& e) {
        throw IngestError(e.what());
    }
    throw IngestError(fmt::format("{}: no such map file, and not a bundled preset ({})", textio::printable(spec),
                                  fmt::join(map_preset_names(), ", ")));
}

}  // namespace

const char* map_key(MapChannel c) { return kKeys[static_cast<int>(c)]; }

std::vector<std::string> map_preset_names() {
    std::vector<std::string> names;
    for (const auto& [name, text] : bundled_map_presets()) names.push_back(name);
    return names;
}

ChannelMap load_channel_map(const std::string& spec, Format format) {
    if (spec.empty()) return format == Format::Shdr ? shdr_defaults() : csv_defaults();
    std::string origin;
    const nlohmann::json j = read_map(spec, origin);
    return apply_channel_map(j, origin, format);
}

ChannelMap parse_channel_map(std::string_view text, const std::string& origin, Format format) {
    nlohmann::json j;
    try {
        j = textio::parse_json(text, origin);
    } catch (const textio::TextError& e) {
        throw IngestError(e.what());
    }
    return apply_channel_map(j, origin, format);
}

ChannelMap apply_channel_map(const nlohmann::json& j, const std::string& origin, Format format) {
    ChannelMap m = format == Format::Shdr ? shdr_defaults() : csv_defaults();
    m.origin = origin;
    if (!j.is_object()) throw IngestError(fmt::format("{}: expected a JSON object mapping channels to columns or keys", origin));
    auto string_of = [&](const nlohmann::json& v, const std::string& key) {
        if (!v.is_string()) throw IngestError(fmt::format("{}: key '{}': expected a string", origin, key));
        return v.get<std::string>();
    };
    for (const auto& [key, value] : j.items()) {
        check_applies(key, format, origin);
        if (key == "description") {
            (void)string_of(value, key);
        } else if (key == "units") {
            if (!value.is_object()) throw IngestError(fmt::format("{}: key 'units': expected an object", origin));
            for (const auto& [u, v] : value.items()) {
                std::optional<std::string>* dst = u == "length" ? &m.length_unit : u == "feed" ? &m.feed_unit
                                                : u == "spindle" ? &m.spindle_unit : u == "time" ? &m.time_unit
                                                : u == "angle" ? &m.angle_unit : nullptr;
                if (!dst)
                    throw IngestError(fmt::format("{}: key 'units.{}': expected length, feed, spindle, time or angle", origin, u));
                check_applies("units." + u, format, origin);
                *dst = string_of(v, "units." + u);
            }
        } else if (key == "sample_period_ms") {
            if (!value.is_number() || !(value.get<double>() > 0) || value.get<double>() > 3.6e6)
                throw IngestError(fmt::format("{}: key 'sample_period_ms': expected a positive number of milliseconds", origin));
            m.sample_period_ms = value.get<double>();
        } else if (key == "block_prefix") {
            m.block_prefix = string_of(value, key);
        } else {
            const auto it = std::find(kKeys.begin(), kKeys.end(), key);
            if (it == kKeys.end())
                throw IngestError(fmt::format("{}: unknown key '{}' (expected {}, units, sample_period_ms, block_prefix, "
                                              "description)", origin, key, fmt::join(kKeys, ", ")));
            std::vector<std::string> keys;
            if (value.is_string()) {
                keys.push_back(value.get<std::string>());
            } else if (value.is_array()) {
                for (const auto& k : value) keys.push_back(string_of(k, key));
            } else {
                throw IngestError(fmt::format("{}: key '{}': expected a column/key name or a list of them", origin, key));
            }
            m.candidates[static_cast<std::size_t>(it - kKeys.begin())] = std::move(keys);
        }
    }
    return m;
}

}  // namespace cutload::motion_io::detail
