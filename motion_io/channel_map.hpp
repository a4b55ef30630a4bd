// Internal to motion_io: which CSV columns or SHDR data items feed which channel. One JSON map
// format for both (docs/formats.md, "Map file"): a channel names one column/key or a list of
// candidates in priority order, plus units, plus (CSV) a sample period for exports without a time
// column. Maps come from a file or from the presets bundled with cutload (data/maps/*.json).
#pragma once

#include "motion_io/motion_io.hpp"
#include "motion_io/shdr.hpp"

#include <nlohmann/json_fwd.hpp>

#include <array>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace cutload::motion_io::detail {

enum class MapChannel : int {
    Position,                       // SHDR 3-D path position "x y z"
    X, Y, Z,                        // actual axis positions
    XCmd, YCmd, ZCmd,               // commanded axis positions (the interpolator's output)
    A, B, C,                        // rotary axes, deg (latched with the linear ones)
    Feed, Spindle, Block,
    Tool,                           // tool number in the spindle (CSV)
    T, TPos, TFeed, TSpindle,       // CSV time columns
    Count
};
inline constexpr int kMapChannels = static_cast<int>(MapChannel::Count);

// The JSON key of a channel ("position", "x", ..., "x_cmd", ..., "t_spindle").
const char* map_key(MapChannel c);

struct ChannelMap {
    std::array<std::vector<std::string>, kMapChannels> candidates;
    std::optional<std::string> length_unit, feed_unit, spindle_unit, time_unit, angle_unit;
    std::optional<double> sample_period_ms;   // CSV without a time column: row k is at k * period
    std::optional<std::string> block_prefix;  // block values are numbers: named prefix + integer
    std::string origin;                       // "map file X" / "preset Y"; empty: built-in defaults

    const std::vector<std::string>& operator[](MapChannel c) const { return candidates[static_cast<int>(c)]; }
};

// The built-in defaults of a format (Csv or Shdr) with the map `spec` laid over them: a file path,
// or the name of a bundled preset; empty: defaults only. Throws IngestError naming the file and key.
ChannelMap load_channel_map(const std::string& spec, Format format);
// The same for a map's JSON text in memory; `origin` names it in errors.
ChannelMap parse_channel_map(std::string_view text, const std::string& origin, Format format);
// The same for a parsed document.
ChannelMap apply_channel_map(const nlohmann::json& map, const std::string& origin, Format format);

// Names of the bundled presets (data/maps/*.json without the extension), sorted.
std::vector<std::string> map_preset_names();

// The public SHDR view of a channel map (motion_io/shdr.hpp), units defaulting to MTConnect's.
ShdrKeyMap shdr_key_map(const ChannelMap& m);

}  // namespace cutload::motion_io::detail
