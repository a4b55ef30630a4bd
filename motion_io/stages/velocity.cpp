#include "stages/velocity.hpp"

#include <algorithm>
#include <cmath>

namespace cutload::motion_io::detail {

double limit_slope(double slope, std::optional<double> d_left, std::optional<double> d_right, double h_max, double tol) {
    if (!d_left && !d_right) return slope;
    double lo = 0, hi = 0;
    if (d_left && d_right) {
        const double m = 3 * std::min(std::abs(*d_left), std::abs(*d_right));
        if (*d_left > 0 && *d_right > 0) hi = m;
        if (*d_left < 0 && *d_right < 0) lo = -m;
    } else {
        const double d = d_left ? *d_left : *d_right;
        (d > 0 ? hi : lo) = 3 * d;
    }
    // A slope off the monotone bound by e moves the Hermite on an interval of h seconds by at most
    // h e / 4 (|h10(u)| + |h11(u)| = u (1 - u) <= 1/4), both ends together.
    const double widen = h_max > 0 ? 4 * tol / h_max : 0.0;
    return std::clamp(slope, lo - widen, hi + widen);
}

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
        limit(next_);
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

void Velocity::limit(std::size_t j) {
    Knot& k = knots_[j];
    const Knot* left = j > 0 && knots_[j - 1].t_s < k.t_s ? &knots_[j - 1] : nullptr;
    const Knot* right = j + 1 < knots_.size() && knots_[j + 1].t_s > k.t_s ? &knots_[j + 1] : nullptr;
    if (!left && !right) return;
    const double h_max = std::max(left ? k.t_s - left->t_s : 0.0, right ? right->t_s - k.t_s : 0.0);
    // The secants of one axis's positions (p: the knot's array of them) left and right of the knot.
    auto limited = [&](double slope, double (Knot::*p)[3], int a, double tol) {
        std::optional<double> d_left, d_right;
        if (left) d_left = ((k.*p)[a] - (left->*p)[a]) / (k.t_s - left->t_s);
        if (right) d_right = ((right->*p)[a] - (k.*p)[a]) / (right->t_s - k.t_s);
        return limit_slope(slope, d_left, d_right, h_max, tol);
    };
    const bool linear = limit_.linear && h_max > limit_.linear_min_interval_s;
    for (int a = 0; a < 3; ++a) {
        if (linear) k.v_mm_s[a] = limited(k.v_mm_s[a], &Knot::p_mm, a, limit_.tol_mm);
        if (limit_.rotary) k.rot_vel_deg_s[a] = limited(k.rot_vel_deg_s[a], &Knot::rot_deg, a, limit_.tol_deg);
    }
}

}  // namespace cutload::motion_io::detail
