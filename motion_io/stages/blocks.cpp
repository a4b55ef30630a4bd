#include "stages/blocks.hpp"

namespace cutload::motion_io::detail {

void BlockAttribution::begin_session() {
    readings_.clear();
    current_ = -1;
    emit_begin_session();
}

void BlockAttribution::grid(std::span<GridSample> batch) {
    for (GridSample& s : batch) {
        if (current_ < 0 && !readings_.empty()) current_ = readings_.front().second;
        while (!readings_.empty() && readings_.front().first <= s.t_s) {
            current_ = readings_.front().second;
            readings_.pop_front();
        }
        s.block = current_;
    }
    emit(batch);
}

}  // namespace cutload::motion_io::detail
