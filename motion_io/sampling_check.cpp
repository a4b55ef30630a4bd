// Coarse data said out loud: how finely a log's positions are written and how often they are
// sampled, against what a force prediction needs (docs/formats.md, "Coarse data").
#include "channel_map.hpp"
#include "pipeline.hpp"

#include <fmt/format.h>

#include <charconv>
#include <cmath>
#include <numeric>

namespace cutload::motion_io {
namespace detail {
namespace {

// The digits of a number as written and the place of its last digit: "-1.98E+02" -> (198, 0),
// "258.428" -> (258428, -3), "0,125" -> (125, -3). False for text that is not a plain decimal.
bool written_digits(std::string_view s, std::int64_t& digits, int& place) {
    std::size_t i = 0;
    if (i < s.size() && (s[i] == '+' || s[i] == '-')) ++i;
    digits = 0;
    int decimals = 0, significant = 0;
    bool point = false, any = false;
    for (; i < s.size(); ++i) {
        const char c = s[i];
        if (c >= '0' && c <= '9') {
            any = true;
            if (digits != 0 || c != '0') ++significant;
            if (significant > 18) return false;
            digits = digits * 10 + (c - '0');
            decimals += point;
        } else if ((c == '.' || c == ',') && !point) {
            point = true;
        } else {
            break;
        }
    }
    if (!any) return false;
    int exponent = 0;
    if (i < s.size()) {
        if (s[i] != 'e' && s[i] != 'E') return false;
        ++i;
        if (i < s.size() && s[i] == '+') ++i;
        const auto r = std::from_chars(s.data() + i, s.data() + s.size(), exponent);
        if (r.ec != std::errc() || r.ptr != s.data() + s.size()) return false;
    }
    place = exponent - decimals;
    return true;
}

}  // namespace

void PositionResolution::add(int axis, std::string_view text, double factor_mm) {
    std::int64_t digits = 0;
    int place = 0;
    Axis& a = axes_[static_cast<std::size_t>(axis)];
    if (!written_digits(text, digits, place)) {
        a.have_prev = false;
        return;
    }
    a.factor_mm = factor_mm;
    if (a.have_prev && place == a.prev_place && digits != a.prev_digits) {
        Bucket& b = a.buckets[place];
        const auto delta = static_cast<std::uint64_t>(digits > a.prev_digits ? digits - a.prev_digits : a.prev_digits - digits);
        ++b.pairs;
        if (b.gcd != 1) b.gcd = std::gcd(b.gcd, delta);
        for (auto& d : b.deltas) {
            if (d == delta) break;
            if (d == 0) {
                d = delta;
                break;
            }
        }
        if (b.example.empty()) b.example = std::string(text);
    }
    a.have_prev = true;
    a.prev_place = place;
    a.prev_digits = digits;
}

std::optional<PositionResolution::Step> PositionResolution::step() const {
    // Fewer moving pairs than this at the dominant place: a few moves tell nothing reliable.
    constexpr std::size_t kMinPairs = 8;
    std::optional<Step> coarsest;
    for (const Axis& a : axes_) {
        const Bucket* best = nullptr;
        int best_place = 0;
        for (const auto& [place, b] : a.buckets)
            if (!best || b.pairs > best->pairs) best = &b, best_place = place;
        if (!best || best->pairs < kMinPairs) continue;
        const bool varied = best->deltas[2] != 0;
        const double step = std::pow(10.0, best_place) * static_cast<double>(varied ? best->gcd : 1) * a.factor_mm;
        if (!coarsest || step > coarsest->step_mm) coarsest = Step{step, best->example};
    }
    return coarsest;
}

void report_reader_facts(Diagnostics& diag, IngestReport& report) {
    const ReaderFacts& f = diag.facts();
    report.spindle_max_rpm = f.spindle_max_abs_rpm;
    report.commanded_positions = f.commanded_positions;
    for (std::size_t k = 0; k < 3; ++k)
        if (f.rotary[k]) report.rotary_axes += char('a' + k);
    const auto step = f.resolution.step();
    if (!step) return;
    // Rounded to the printed place, so 1 mm reads 1 and not 0.99999999.
    report.position_step_mm = std::stod(fmt::format("{:.6g}", step->step_mm));
    if (*report.position_step_mm <= kQuantizedStepMm * (1 + 1e-9)) return;
    const auto pos = report.channels.find("pos");
    const double dt_s = pos == report.channels.end() ? 0.0 : pos->second.interval.median_s;
    std::string effect = "velocities from positions, and feed per tooth, chip thickness and force with them, are uncertain";
    if (dt_s > 0) {
        // Two readings dt apart, each off by up to half a step: the difference is off by up to a
        // step, the central difference over 2 dt by up to step / (2 dt).
        const double dv_mm_s = *report.position_step_mm / (2 * dt_s);
        effect = fmt::format("a velocity from positions {:.3g} ms apart is uncertain by up to +-{:.3g} mm/s (+-{:.0f} mm/min), and "
                             "feed per tooth, chip thickness and force with it",
                             dt_s * 1e3, dv_mm_s, dv_mm_s * 60);
        if (report.feed_repaired_max_mm_min > 0)
            effect += fmt::format(" (+-{:.0f} % at the log's highest feed, {:.0f} mm/min)",
                                  100 * dv_mm_s * 60 / report.feed_repaired_max_mm_min, report.feed_repaired_max_mm_min);
    }
    diag.warn("position_quantized", 0,
              fmt::format("positions are written in steps of {:g} mm (e.g. '{}'), coarser than {:g} mm: {}",
                          *report.position_step_mm, step->example, kQuantizedStepMm, effect));
}

}  // namespace detail

SamplingCheck check_sampling(const IngestReport& report, int teeth) {
    SamplingCheck c;
    if (const auto pos = report.channels.find("pos"); pos != report.channels.end()) c.sample_period_s = pos->second.interval.median_s;
    c.position_step_mm = report.position_step_mm;
    c.position_quantized = report.position_step_mm && *report.position_step_mm > detail::kQuantizedStepMm * (1 + 1e-9);
    c.spindle_max_rpm = report.spindle_max_rpm;
    if (c.spindle_max_rpm > 0 && teeth > 0) c.tooth_period_s = 60.0 / (c.spindle_max_rpm * teeth);
    if (c.tooth_period_s > 0 && c.sample_period_s > c.tooth_period_s) {
        c.sampling_coarse = true;
        c.warnings.push_back(
            {"sampling_coarse",
             fmt::format("positions are sampled every {:.3g} ms, longer than a tooth period ({:.3g} ms at {:.0f} rpm with {} "
                         "teeth; {:.1f} teeth pass between two samples): the path within a tooth engagement is interpolated, "
                         "not logged, so entries, corners and feed changes shorter than {:.3g} ms are smoothed over and "
                         "per-tooth peaks follow the interpolated path",
                         c.sample_period_s * 1e3, c.tooth_period_s * 1e3, c.spindle_max_rpm, teeth,
                         c.sample_period_s / c.tooth_period_s, c.sample_period_s * 1e3),
             1});
    }
    return c;
}

std::vector<std::string> map_presets() { return detail::map_preset_names(); }

}  // namespace cutload::motion_io
