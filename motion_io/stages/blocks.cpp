#include "stages/blocks.hpp"

namespace cutload::motion_io::detail {

std::int32_t BlockAttribution::Channel::at(double t_s) {
    if (current < 0 && !readings.empty()) current = readings.front().second;
    while (!readings.empty() && readings.front().first <= t_s) {
        current = readings.front().second;
        readings.pop_front();
    }
    return current;
}

void BlockAttribution::begin_session() {
    blocks_ = Channel{};
    tools_ = Channel{};
    emit_begin_session();
}

void BlockAttribution::record(const Record& r) {
    if (r.ch == Chan::Tool)
        tools_.readings.emplace_back(r.t_s, static_cast<std::int32_t>(r.v[0]));
    else
        blocks_.readings.emplace_back(r.t_s, r.block);
}

void BlockAttribution::grid(std::span<GridSample> batch) {
    for (GridSample& s : batch) {
        s.block = blocks_.at(s.t_s);
        s.tool = tools_.at(s.t_s);
    }
    emit(batch);
}

}  // namespace cutload::motion_io::detail
