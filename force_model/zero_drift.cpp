// Zero offset and drift of a charge-amplifier record (see zero_drift.hpp).
#include "force_model/zero_drift.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <stdexcept>

namespace cutload::force_model {

const char* zero_source_name(ZeroSource s) {
    switch (s) {
        case ZeroSource::LeadIn: return "lead_in";
        case ZeroSource::IdleTail: return "idle_tail";
        case ZeroSource::Given: return "given";
        case ZeroSource::Estimated: return "estimated";
        case ZeroSource::None: break;
    }
    return "none";
}

const char* drift_source_name(DriftSource s) {
    switch (s) {
        case DriftSource::Idle: return "idle";
        case DriftSource::Cut: return "cut";
        case DriftSource::None: break;
    }
    return "none";
}

std::array<double, 3> robust_slope_per_s(const std::vector<double>& t_s, const std::vector<std::array<double, 3>>& v) {
    const std::size_t n = std::min(t_s.size(), v.size());
    if (n < 2) throw std::invalid_argument("robust_slope_per_s: fewer than two points");
    const std::size_t half = n / 2;
    std::array<double, 3> out{};
    std::vector<double> slopes;
    slopes.reserve(n - half);
    for (std::size_t ax = 0; ax < 3; ++ax) {
        slopes.clear();
        for (std::size_t i = 0; i + half < n; ++i) {
            const double dt = t_s[i + half] - t_s[i];
            if (dt > 0) slopes.push_back((v[i + half][ax] - v[i][ax]) / dt);
        }
        if (slopes.empty()) throw std::invalid_argument("robust_slope_per_s: times do not increase");
        const auto mid = slopes.begin() + static_cast<long>(slopes.size() / 2);
        std::nth_element(slopes.begin(), mid, slopes.end());
        out[ax] = *mid;
    }
    return out;
}

nlohmann::json to_json(const ZeroLine& z) {
    return {{"source", zero_source_name(z.source)},
            {"t_s", z.t_s},
            {"N", z.zero_N},
            {"drift_source", drift_source_name(z.drift_source)},
            {"drift_N_per_s", z.drift_N_per_s}};
}

}  // namespace cutload::force_model
