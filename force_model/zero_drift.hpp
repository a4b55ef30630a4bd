// Zero offset and drift of a charge-amplifier record. A charge amplifier reads zero when it is reset
// and then drifts (leakage, the dynamometer warming up): what it records is the force plus an offset
// that grows about linearly in time. Both `cutload calibrate` and `cutload compare` remove it as a
// line, zero(t) = zero_N + drift_N_per_s (t - t_s), and report where it came from.
#pragma once

#include <nlohmann/json_fwd.hpp>

#include <array>
#include <cmath>
#include <cstddef>
#include <vector>

namespace cutload::force_model {

// Where the zero offset came from.
enum class ZeroSource {
    None,        // not removed
    LeadIn,      // idle recording before the cut
    IdleTail,    // idle recording after the cut
    Given,       // given by the user
    Estimated,   // the air between tooth passes inside the cut (partial immersion)
};
const char* zero_source_name(ZeroSource s);   // none, lead_in, idle_tail, given, estimated

// Where the drift came from.
enum class DriftSource {
    None,   // not found: the zero is removed as a constant
    Idle,   // idle recording on both sides of the cut (or air throughout the compared span)
    Cut,    // the trend of the steady revolution means (the cutting force of a steady cut is constant)
};
const char* drift_source_name(DriftSource s);   // none, idle, cut

// Forces are in the measurement's axes (tool / machine axes once mapped).
struct ZeroLine {
    ZeroSource source = ZeroSource::None;
    DriftSource drift_source = DriftSource::None;
    std::array<double, 3> zero_N{};            // the offset at time t_s
    double t_s = 0;
    std::array<double, 3> drift_N_per_s{};

    std::array<double, 3> at(double t) const {
        return {zero_N[0] + drift_N_per_s[0] * (t - t_s), zero_N[1] + drift_N_per_s[1] * (t - t_s),
                zero_N[2] + drift_N_per_s[2] * (t - t_s)};
    }
};

// A drift is taken only where it stands out from the noise: some axis's slope at least this many
// standard errors from zero. Fitting a drift that is not there only adds the noise of its slope to
// the zero offset away from where it was measured. At 5, chance alone flags an axis about once in
// a million records; a drift of 5 % of the cutting force over a record of a few hundred revolutions
// stands at about 20.
inline constexpr double kDriftSignificance = 5.0;
inline bool drift_significant(const std::array<double, 3>& slope, const std::array<double, 3>& standard_error) {
    for (std::size_t ax = 0; ax < 3; ++ax)
        if (std::abs(slope[ax]) > kDriftSignificance * standard_error[ax]) return true;
    return false;
}

// Slope per axis of points (t_s[i], v[i]) that should lie on a line apart from noise and a few
// outliers: the median of the slopes of the pairs half the run apart (i, i + n/2). It costs O(n)
// and shrugs off a ramp revolution or two at either end, which least squares would not. Needs n >= 2.
std::array<double, 3> robust_slope_per_s(const std::vector<double>& t_s, const std::vector<std::array<double, 3>>& v);

// {"source", "t_s", "N" (the offset at t_s), "drift_source", "drift_N_per_s"}:
// zero(t) = N + drift_N_per_s (t - t_s).
nlohmann::json to_json(const ZeroLine& z);

}  // namespace cutload::force_model
