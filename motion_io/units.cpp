// Unit names accepted in CSV headers, --units / --feed-units and SHDR map files.
#include "pipeline.hpp"

#include <algorithm>
#include <cctype>
#include <map>
#include <stdexcept>

namespace cutload::motion_io::detail {
namespace {

double lookup(const std::map<std::string, double, std::less<>>& table, std::string_view unit, const char* kind) {
    const std::string u = normalise_unit(unit);
    if (auto it = table.find(u); it != table.end()) return it->second;
    std::string expected;
    for (const auto& [name, factor] : table) expected += (expected.empty() ? "" : ", ") + name;
    throw std::invalid_argument("unknown " + std::string(kind) + " unit '" + std::string(unit) +
                                "' (expected one of " + expected + ")");
}

const std::map<std::string, double, std::less<>>& length_units() {
    static const std::map<std::string, double, std::less<>> t{
        {"mm", 1.0}, {"um", 1e-3}, {"cm", 10.0}, {"m", 1000.0}, {"in", 25.4}, {"inch", 25.4}};
    return t;
}

const std::map<std::string, double, std::less<>>& time_units() {
    static const std::map<std::string, double, std::less<>> t{
        {"s", 1.0}, {"sec", 1.0}, {"ms", 1e-3}, {"us", 1e-6}, {"min", 60.0}};
    return t;
}

}  // namespace

std::string normalise_unit(std::string_view unit) {
    std::string u;
    for (char c : unit)
        if (!std::isspace(static_cast<unsigned char>(c))) u += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return u;
}

double length_factor_mm(std::string_view unit) { return lookup(length_units(), unit, "length"); }

double time_factor_s(std::string_view unit) { return lookup(time_units(), unit, "time"); }

double feed_factor_mm_min(std::string_view unit) {
    // A feed unit is length/time: "mm/min", "in/min", "mm/s", "m/min", ...
    const std::string u = normalise_unit(unit);
    const auto slash = u.find('/');
    if (slash == std::string::npos)
        throw std::invalid_argument("unknown feed unit '" + std::string(unit) +
                                    "' (expected length/time such as mm/min, mm/s, in/min)");
    const double len = length_factor_mm(u.substr(0, slash));
    const double per_s = time_factor_s(u.substr(slash + 1));
    return len * 60.0 / per_s;
}

double angle_factor_deg(std::string_view unit) {
    static const std::map<std::string, double, std::less<>> t{{"deg", 1.0}, {"rad", 57.29577951308232}};
    return lookup(t, unit, "angle");
}

double speed_factor_rpm(std::string_view unit) {
    static const std::map<std::string, double, std::less<>> t{
        {"rpm", 1.0}, {"1/min", 1.0}, {"rev/min", 1.0}, {"rev/s", 60.0}, {"rps", 60.0}, {"hz", 60.0}};
    return lookup(t, unit, "spindle speed");
}

}  // namespace cutload::motion_io::detail
