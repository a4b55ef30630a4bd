// The SHDR key map (docs/formats.md, "Key map"): the public view of the channel map that the live
// sources use, read by the one channel-map loader (channel_map.cpp) so a map means the same to
// the file reader, the replay adapter and the live clients.
#include "motion_io/shdr.hpp"
#include "channel_map.hpp"
#include "pipeline.hpp"

namespace cutload::motion_io {

namespace detail {

ShdrKeyMap shdr_key_map(const ChannelMap& m) {
    ShdrKeyMap k;
    k.position = m[MapChannel::Position];
    k.x = m[MapChannel::X];
    k.y = m[MapChannel::Y];
    k.z = m[MapChannel::Z];
    k.feed = m[MapChannel::Feed];
    k.spindle = m[MapChannel::Spindle];
    k.block = m[MapChannel::Block];
    k.length_unit = m.length_unit.value_or(k.length_unit);
    k.feed_unit = m.feed_unit.value_or(k.feed_unit);
    k.spindle_unit = m.spindle_unit.value_or(k.spindle_unit);
    return k;
}

}  // namespace detail

ShdrKeyMap default_shdr_key_map() { return detail::shdr_key_map(detail::load_channel_map("", Format::Shdr)); }

ShdrKeyMap load_shdr_key_map(const std::string& path) { return detail::shdr_key_map(detail::load_channel_map(path, Format::Shdr)); }

ShdrUnitFactors shdr_unit_factors(const ShdrKeyMap& map, const ReadOptions& opt) {
    ShdrUnitFactors f;
    f.length_mm = detail::length_factor_mm(opt.length_unit.value_or(map.length_unit));
    f.feed_mm_min = detail::feed_factor_mm_min(
        opt.feed_unit.value_or(opt.length_unit && !opt.feed_unit ? *opt.length_unit + "/s" : map.feed_unit));
    f.spindle_rpm = detail::speed_factor_rpm(map.spindle_unit);
    return f;
}

}  // namespace cutload::motion_io
