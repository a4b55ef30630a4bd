#include "stages/unwrap.hpp"

#include <cmath>

namespace cutload::motion_io::detail {

double nearest_equivalent_deg(double deg, double previous_deg) {
    return deg + 360.0 * std::round((previous_deg - deg) / 360.0);
}

void UnwrapRotary::begin_session() {
    have_prev_ = false;
    emit_begin_session();
}

void UnwrapRotary::record(const Record& r) {
    if (!facts_.any_rotary()) {
        emit(Flow::Positions, r);
        return;
    }
    Record out = r;
    for (int k = 0; k < 3; ++k) {
        if (!facts_.rotary[std::size_t(k)]) continue;
        if (have_prev_) out.rot_deg[k] = nearest_equivalent_deg(r.rot_deg[k], prev_deg_[k]);
        prev_deg_[k] = out.rot_deg[k];
    }
    have_prev_ = true;
    emit(Flow::Positions, out);
}

}  // namespace cutload::motion_io::detail
