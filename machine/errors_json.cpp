// Geometric errors of one axis from JSON: ISO 230-1 names with a unit suffix ("EXX_um",
// "EC0Y_urad"), each a number or (component errors only) a table against the axis position.
#include "json_reader.hpp"

#include <fmt/format.h>

#include <cmath>
#include <string>

namespace cutload::machine::detail {
namespace {

using nlohmann::json;

// Beyond this a table is not a measurement report any more; refusing keeps memory bounded.
constexpr std::size_t kMaxTablePoints = 100000;

constexpr double kPi = 3.14159265358979323846;

// Scale from the key's unit to mm (translations) or rad (rotations); 0 if the unit does not fit.
double unit_scale(const std::string& unit, bool rotation) {
    if (!rotation) {
        if (unit == "mm") return 1;
        if (unit == "um") return 1e-3;
        return 0;
    }
    if (unit == "rad") return 1;
    if (unit == "mrad") return 1e-3;
    if (unit == "urad") return 1e-6;
    if (unit == "deg") return kPi / 180;
    if (unit == "arcsec") return kPi / (180 * 3600);
    return 0;
}

struct ErrorKey {
    int component = 0;     // ErrorComponent
    bool location = false;
    char axis = 0;
    double scale = 1;
};

ErrorKey parse_key(const std::string& key, const Axis& axis, const std::string& path) {
    static const std::string kDirs = "XYZABC";
    const auto us = key.find('_');
    const std::string name = key.substr(0, us);
    const bool shape_ok = (name.size() == 3 || (name.size() == 4 && name[2] == '0')) && name[0] == 'E' &&
                          kDirs.find(name[1]) != std::string::npos;
    if (!shape_ok)
        fail(path, fmt::format("unknown key: expected an ISO 230-1 error name with a unit, such as E{}{}_um "
                               "(component) or EC0{}_urad (location), or reference_point_mm",
                               'X', axis.name, axis.name));
    ErrorKey k;
    k.component = static_cast<int>(kDirs.find(name[1]));
    k.location = name.size() == 4;
    k.axis = name.back();
    if (k.axis != axis.name)
        fail(path, fmt::format("names axis {}, but it is listed under axis {}", k.axis, axis.name));
    const bool rotation = k.component >= kErrA;
    if (us == std::string::npos)
        fail(path, rotation ? "needs a unit suffix: _rad, _mrad, _urad, _deg or _arcsec"
                            : "needs a unit suffix: _mm or _um");
    const std::string unit = key.substr(us + 1);
    k.scale = unit_scale(unit, rotation);
    if (k.scale == 0)
        fail(path, fmt::format("unit '{}' does not fit a {}: use {}", unit, rotation ? "rotation" : "translation",
                               rotation ? "_rad, _mrad, _urad, _deg or _arcsec" : "_mm or _um"));
    if (k.location && axis.type == AxisType::Linear && !rotation)
        fail(path, fmt::format("a linear axis has no position, only a direction: give its squareness "
                               "(EA0{0}, EB0{0}, EC0{0}) and the offsets on the rotary axes",
                               axis.name));
    return k;
}

ErrorTable parse_table(const json& v, const Axis& axis, double scale, const std::string& path) {
    ErrorTable t;
    if (v.is_number()) {
        t.at = {0};
        t.value = {number_at(v, path) * scale};
        return t;
    }
    const std::string at_key = axis.rotary() ? "at_deg" : "at_mm";
    if (!v.is_object())
        fail(path, fmt::format("expected a number (constant) or a table {{\"{}\": [...], \"values\": [...]}}", at_key));
    ObjectReader r(v, path);
    const json& at = r.at(at_key);
    const json& values = r.at("values");
    r.reject_unknown();
    if (!at.is_array() || at.size() < 2) fail(r.key_path(at_key), "expected an array of at least 2 positions");
    if (!values.is_array() || values.size() != at.size())
        fail(r.key_path("values"), fmt::format("expected an array of {} numbers, one per position", at.size()));
    if (at.size() > kMaxTablePoints)
        fail(r.key_path(at_key), fmt::format("has {} points; at most {} are accepted", at.size(), kMaxTablePoints));
    for (std::size_t i = 0; i < at.size(); ++i) {
        t.at.push_back(number_at(at[i], index_key(r.key_path(at_key), i)));
        t.value.push_back(number_at(values[i], index_key(r.key_path("values"), i)) * scale);
        if (i > 0 && !(t.at[i] > t.at[i - 1]))
            fail(index_key(r.key_path(at_key), i), "positions must increase strictly");
    }
    if (axis.rotary() && std::abs(t.at.back() - t.at.front() - 360) < 1e-9) {
        // A table over exactly one turn describes a periodic error: it must close on itself.
        if (std::abs(t.value.back() - t.value.front()) > 1e-12 * std::max(1.0, std::abs(t.value.front())))
            fail(r.key_path("values"), "a table over one full turn must end with the value it starts with");
        t.periodic = true;
    }
    return t;
}

}  // namespace

AxisErrors parse_axis_errors(const json& j, const Axis& axis, const std::string& path) {
    ObjectReader r(j, path);
    AxisErrors e;
    // Rotations act about the pivot of a rotary axis unless another point on its line is given.
    e.reference_point_mm = axis.rotary() ? axis.pivot_mm : Eigen::Vector3d::Zero();
    std::array<std::string, kErrorComponents> seen_component, seen_location;
    for (const auto& [key, value] : j.items()) {
        const std::string kp = r.key_path(key);
        r.mark_used(key);
        if (key == "reference_point_mm") {
            e.reference_point_mm = vec3_at(value, kp);
            if (axis.rotary()) {
                const Eigen::Vector3d off = e.reference_point_mm - axis.pivot_mm;
                const double from_line = (off - off.dot(axis.direction) * axis.direction).norm();
                if (from_line > 1e-6)
                    fail(kp, fmt::format("must lie on the {} axis line (it is {:.6g} mm off it)", axis.name, from_line));
            }
            continue;
        }
        const ErrorKey k = parse_key(key, axis, kp);
        auto& seen = k.location ? seen_location : seen_component;
        if (!seen[static_cast<std::size_t>(k.component)].empty())
            fail(kp, fmt::format("the same error is already given as {}", seen[static_cast<std::size_t>(k.component)]));
        seen[static_cast<std::size_t>(k.component)] = key;
        if (k.location) {
            if (!value.is_number()) fail(kp, "a location error is a constant: expected a number");
            e.location[static_cast<std::size_t>(k.component)] = number_at(value, kp) * k.scale;
        } else {
            e.component[static_cast<std::size_t>(k.component)] = parse_table(value, axis, k.scale, kp);
        }
    }
    return e;
}

}  // namespace cutload::machine::detail
