// Internal: reading a machine definition's JSON objects with errors that name the key path.
// Every key read is remembered, so leftovers (typos such as "pviot_mm") are reported instead of
// silently ignored.
#pragma once

#include "machine/machine.hpp"

#include <nlohmann/json.hpp>

#include <set>
#include <string>

namespace cutload::machine::detail {

std::string join_key(const std::string& path, const std::string& key);
std::string index_key(const std::string& path, std::size_t i);

[[noreturn]] void fail(const std::string& path, const std::string& what);

// A finite number at `path`, or MachineError.
double number_at(const nlohmann::json& v, const std::string& path);
// [x, y, z] of finite numbers.
Eigen::Vector3d vec3_at(const nlohmann::json& v, const std::string& path);
// A direction: a vector of length 1 within 1e-3 (normalised to exactly 1; [0, 0.7071, 0.7071] is
// fine), else MachineError saying its length.
Eigen::Vector3d unit_at(const nlohmann::json& v, const std::string& path);

class ObjectReader {
public:
    ObjectReader(const nlohmann::json& j, std::string path);

    bool has(const std::string& key) const;
    const nlohmann::json& at(const std::string& key);   // required
    const nlohmann::json* find(const std::string& key); // optional: nullptr when absent or null
    std::string string(const std::string& key);
    std::string key_path(const std::string& key) const { return join_key(path_, key); }
    const std::string& path() const { return path_; }
    const nlohmann::json& object() const { return j_; }
    void mark_used(const std::string& key) { used_.insert(key); }
    // Call after reading every known key.
    void reject_unknown() const;

private:
    const nlohmann::json& j_;
    std::string path_;
    std::set<std::string> used_;
};

// "errors" object parsing for one axis (errors_json.cpp).
AxisErrors parse_axis_errors(const nlohmann::json& j, const Axis& axis, const std::string& path);

}  // namespace cutload::machine::detail
