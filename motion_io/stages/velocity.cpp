#include "stages/velocity.hpp"

#include <algorithm>

namespace cutload::motion_io::detail {

void Velocity::begin_session() {
    knots_.clear();
    next_ = 0;
    period_s_ = 0;
    emit_begin_session();
}

void Velocity::tick(const Tick& t) {
    if (t.replaces_previous) {
        // Not yet given a velocity: the newest knot never is before a later one arrives.
        std::copy(t.p_mm, t.p_mm + 3, knots_.back().p_mm);
        std::copy(t.rot_deg, t.rot_deg + 3, knots_.back().rot_deg);
        return;
    }
    period_s_ = t.period_s;
    Knot k;
    k.t_s = t.t_s;
    std::copy(t.p_mm, t.p_mm + 3, k.p_mm);
    std::copy(t.rot_deg, t.rot_deg + 3, k.rot_deg);
    knots_.push_back(k);
    finalise(false);
}

void Velocity::end_session(SessionSummary& s) {
    period_s_ = s.period_s;
    finalise(true);
    knots_.clear();
    next_ = 0;
    emit_end_session(s);
}

void Velocity::finalise(bool final) {
    const double H = period_s_ > 0 ? 2 * period_s_ : 0.0;
    while (next_ < knots_.size()) {
        const double tj = knots_[next_].t_s;
        const bool have_right = knots_.size() > next_ + 1 && knots_.back().t_s >= tj + H;
        if (!final && !have_right) break;
        fit(next_, H);
        emit(knots_[next_]);
        ++next_;
        // Keep the left neighbour and everything inside the next knot's window.
        while (next_ >= 2 && next_ < knots_.size() && knots_[0].t_s < knots_[next_].t_s - H) {
            knots_.pop_front();
            --next_;
        }
    }
}

void Velocity::fit(std::size_t j, double H) {
    const double tj = knots_[j].t_s;
    std::size_t lo = j, hi = j;
    while (lo > 0 && (knots_[lo - 1].t_s >= tj - H || lo == j)) --lo;
    while (hi + 1 < knots_.size() && (knots_[hi + 1].t_s <= tj + H || hi == j)) ++hi;
    if (hi == lo) return;
    double mt = 0, mp[3] = {0, 0, 0}, mr[3] = {0, 0, 0};
    for (std::size_t i = lo; i <= hi; ++i) {
        mt += knots_[i].t_s;
        for (int a = 0; a < 3; ++a) mp[a] += knots_[i].p_mm[a], mr[a] += knots_[i].rot_deg[a];
    }
    const double n = static_cast<double>(hi - lo + 1);
    mt /= n;
    double sxx = 0, sxy[3] = {0, 0, 0}, sxr[3] = {0, 0, 0};
    for (std::size_t i = lo; i <= hi; ++i) {
        const double dt = knots_[i].t_s - mt;
        sxx += dt * dt;
        for (int a = 0; a < 3; ++a) {
            sxy[a] += dt * (knots_[i].p_mm[a] - mp[a] / n);
            sxr[a] += dt * (knots_[i].rot_deg[a] - mr[a] / n);
        }
    }
    for (int a = 0; a < 3; ++a) {
        knots_[j].v_mm_s[a] = sxx > 0 ? sxy[a] / sxx : 0.0;
        knots_[j].rot_vel_deg_s[a] = sxx > 0 ? sxr[a] / sxx : 0.0;
    }
}

}  // namespace cutload::motion_io::detail
