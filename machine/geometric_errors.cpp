#include "machine/geometric_errors.hpp"

#include <algorithm>
#include <cmath>

namespace cutload::machine {

double ErrorTable::operator()(double position) const {
    if (value.size() == 1) return value.front();
    double q = position;
    if (periodic) {
        const double span = at.back() - at.front();
        q = at.front() + std::fmod(q - at.front(), span);
        if (q < at.front()) q += span;
    }
    if (q <= at.front()) return value.front();
    if (q >= at.back()) return value.back();
    const auto hi = static_cast<std::size_t>(std::upper_bound(at.begin(), at.end(), q) - at.begin());
    const std::size_t lo = hi - 1;
    const double w = (q - at[lo]) / (at[hi] - at[lo]);
    return value[lo] + w * (value[hi] - value[lo]);
}

bool AxisErrors::any() const {
    for (const auto& c : component)
        if (c) return true;
    for (double v : location)
        if (v != 0) return true;
    return false;
}

Frame small_displacement(const Eigen::Vector3d& t_mm, const Eigen::Vector3d& r_rad, const Eigen::Vector3d& c_mm) {
    const Eigen::Matrix3d R = exp_so3(r_rad);
    return {R, c_mm + t_mm - R * c_mm};
}

}  // namespace cutload::machine
