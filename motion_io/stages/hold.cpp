#include "stages/hold.hpp"

#include <algorithm>

namespace cutload::motion_io::detail {

void HoldValues::begin_session() {
    pos_ = Held{};
    spindle_ = Held{};
    emit_begin_session();
}

void HoldValues::record(const Record& r) {
    Held& h = r.ch == Chan::Pos ? pos_ : spindle_;
    const Flow kind = session_flow(r.ch);
    if (h.have) {
        const double dt = r.t_s - h.last.t_s;
        if (h.n_intervals >= 3) {
            std::array<double, kIntervalRing> sorted = h.intervals;
            const std::size_t n = std::min(h.n_intervals, kIntervalRing);
            std::nth_element(sorted.begin(), sorted.begin() + static_cast<long>(n / 2), sorted.begin() + static_cast<long>(n));
            const double usual = sorted[n / 2];
            // A silence that a dropped glitch left is a lost reading: the interpolant bridges it.
            if (dt > 2 * usual && !r.after_glitch) {
                Record hold = h.last;
                hold.t_s = r.t_s - usual;
                hold.line = r.line;
                emit(kind, hold);
            }
        }
        if (dt > 0) h.intervals[h.n_intervals++ % kIntervalRing] = dt;
    }
    h.last = r;
    h.have = true;
    emit(kind, r);
}

}  // namespace cutload::motion_io::detail
