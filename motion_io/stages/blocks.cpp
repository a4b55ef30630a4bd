#include "stages/blocks.hpp"

namespace cutload::motion_io::detail {

void BlockAttribution::begin_session() {
    readings_.clear();
    current_ = -1;
    emit_begin_session();
}

void BlockAttribution::sample(GridSample& s) {
    if (current_ < 0 && !readings_.empty()) current_ = readings_.front().second;
    while (!readings_.empty() && readings_.front().first <= s.t_s) {
        current_ = readings_.front().second;
        readings_.pop_front();
    }
    s.block = current_;
    emit(s);
}

}  // namespace cutload::motion_io::detail
