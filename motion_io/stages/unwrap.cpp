#include "stages/unwrap.hpp"

#include <cmath>

namespace cutload::motion_io::detail {

double nearest_equivalent_deg(double deg, double previous_deg) {
    // Two equivalents tie when the reading is an odd number of half turns away. The one nearer the
    // reading as shown wins: a head swung from 0 to 180 deg while the adapter said nothing reads
    // 180, not -180 (std::round would take the tie away from zero).
    const double turns = (previous_deg - deg) / 360.0;
    if (std::abs(turns - std::trunc(turns)) == 0.5) return deg + 360.0 * std::trunc(turns);
    return deg + 360.0 * std::round(turns);
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
