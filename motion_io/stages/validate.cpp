#include "stages/validate.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace cutload::motion_io::detail {
namespace {

const char* channel_name(Chan ch) {
    switch (ch) {
        case Chan::Pos: return "position";
        case Chan::AxisX: return "x";
        case Chan::AxisY: return "y";
        case Chan::AxisZ: return "z";
        case Chan::Feed: return "feed";
        case Chan::Spindle: return "spindle";
        case Chan::Block: return "block";
        case Chan::Tool: return "tool";
        case Chan::AxisA: return "a";
        case Chan::AxisB: return "b";
        case Chan::AxisC: return "c";
    }
    return "?";
}

// Which readings stand in for each other when one is lost: positions (3-D or per axis), spindle, the rest.
int group_of(Chan ch) {
    return ch == Chan::Pos || ch == Chan::AxisX || ch == Chan::AxisY || ch == Chan::AxisZ || is_rotary_axis(ch) ? 0
           : ch == Chan::Spindle                                                                            ? 1
                                                                                                            : 2;
}

int values_of(Chan ch) { return ch == Chan::Pos ? 3 : (ch == Chan::Block || ch == Chan::Tool) ? 0 : 1; }

}  // namespace

Validate::Validate(Diagnostics& diag, PhysicalLimits limits) : Stage("validate"), diag_(diag), limits_(limits) {}

void Validate::record(const Record& r) {
    bool& dropped_since = dropped_since_[group_of(r.ch)];
    if (glitch(r)) {
        drop(r);
        dropped_since = true;
        return;
    }
    if (r.ch == Chan::Spindle) {
        if (spike(r)) {
            drop_spike(r);
            dropped_since = true;
            return;
        }
        last_spindle_rpm_ = r.v[0];
        spike_run_ = 0;
        double& max_rpm = diag_.facts().spindle_max_abs_rpm;
        max_rpm = std::max(max_rpm, std::fabs(r.v[0]));
    }
    Record out = r;
    out.after_glitch = r.after_glitch || dropped_since;
    dropped_since = false;
    emit(Flow::Checked, out);
}

bool Validate::spike(const Record& r) {
    const double rpm = std::fabs(r.v[0]);
    // Without a reading before it there is nothing to jump from: the first reading stands.
    if (!last_spindle_rpm_ || rpm <= limits_.plausible_spindle_rpm) return false;
    if (!(rpm > limits_.spike_ratio * std::fabs(*last_spindle_rpm_))) return false;
    return spike_run_ < limits_.max_spike_readings;
}

void Validate::drop_spike(const Record& r) {
    ++dropped_;
    ++spike_run_;
    diag_.warn("glitch_dropped", r.line,
               fmt::format("spindle {:g} rpm, a jump from {:g} rpm beyond the plausible {:g} rpm: no spindle "
                           "accelerates so and a unit mix-up moves every reading; a glitch, dropped",
                           r.v[0], *last_spindle_rpm_, limits_.plausible_spindle_rpm));
}

double Validate::limit_for(Chan ch) const {
    // A rotary axis has no physical range to judge a glitch by (a table counts on past a turn):
    // only the readers' bound on an angle applies.
    return ch == Chan::Feed ? limits_.max_abs_feed_mm_min
           : ch == Chan::Spindle ? limits_.max_abs_spindle_rpm
           : is_rotary_axis(ch) ? kMaxAbsRotaryDeg
                                 : limits_.max_abs_position_mm;
}

bool Validate::glitch(const Record& r) const {
    if (!std::isfinite(r.t_s)) return true;
    const double limit = limit_for(r.ch);
    for (int k = 0; k < values_of(r.ch); ++k)
        if (!(std::fabs(r.v[k]) <= limit)) return true;   // NaN fails the comparison too
    return false;
}

void Validate::drop(const Record& r) {
    ++dropped_;
    std::string what;
    if (!std::isfinite(r.t_s)) {
        what = fmt::format("{} reading with time stamp {}", channel_name(r.ch), r.t_s);
    } else if (r.ch == Chan::Pos) {
        what = fmt::format("position ({:g}, {:g}, {:g}) mm beyond +-{:g} mm", r.v[0], r.v[1], r.v[2],
                           limits_.max_abs_position_mm);
    } else {
        const char* unit = r.ch == Chan::Feed ? "mm/min" : r.ch == Chan::Spindle ? "rpm" : is_rotary_axis(r.ch) ? "deg" : "mm";
        what = fmt::format("{} {:g} {} beyond +-{:g} {}", channel_name(r.ch), r.v[0], unit, limit_for(r.ch), unit);
    }
    diag_.warn("glitch_dropped", r.line,
               what + ": no machine reports that and no unit mix-up explains it; a glitch, dropped");
}

}  // namespace cutload::motion_io::detail
