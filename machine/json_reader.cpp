#include "json_reader.hpp"

#include <fmt/format.h>

#include <cmath>

namespace cutload::machine::detail {

using nlohmann::json;

std::string join_key(const std::string& path, const std::string& key) {
    return path.empty() ? key : path + "." + key;
}

std::string index_key(const std::string& path, std::size_t i) { return fmt::format("{}[{}]", path, i); }

void fail(const std::string& path, const std::string& what) {
    throw MachineError(path.empty() ? what : path + ": " + what);
}

double number_at(const json& v, const std::string& path) {
    if (!v.is_number()) fail(path, "expected a number");
    const double x = v.get<double>();
    if (!std::isfinite(x)) fail(path, "must be finite");
    return x;
}

Eigen::Vector3d vec3_at(const json& v, const std::string& path) {
    if (!v.is_array() || v.size() != 3) fail(path, "expected an array of 3 numbers [x, y, z]");
    Eigen::Vector3d out;
    for (std::size_t i = 0; i < 3; ++i) out[static_cast<int>(i)] = number_at(v[i], index_key(path, i));
    return out;
}

Eigen::Vector3d unit_at(const json& v, const std::string& path) {
    const Eigen::Vector3d d = vec3_at(v, path);
    const double n = d.norm();
    if (std::abs(n - 1) > 1e-3)
        fail(path, fmt::format("must be a unit vector (its length is {:.6g})", n));
    return d / n;
}

ObjectReader::ObjectReader(const json& j, std::string path) : j_(j), path_(std::move(path)) {
    if (!j_.is_object()) fail(path_, "expected a JSON object");
}

bool ObjectReader::has(const std::string& key) const { return j_.contains(key) && !j_.at(key).is_null(); }

const json& ObjectReader::at(const std::string& key) {
    used_.insert(key);
    if (!has(key)) fail(key_path(key), "required key is missing");
    return j_.at(key);
}

const json* ObjectReader::find(const std::string& key) {
    used_.insert(key);
    return has(key) ? &j_.at(key) : nullptr;
}

std::string ObjectReader::string(const std::string& key) {
    const json& v = at(key);
    if (!v.is_string()) fail(key_path(key), "expected a string");
    return v.get<std::string>();
}

void ObjectReader::reject_unknown() const {
    for (const auto& [key, value] : j_.items()) {
        (void)value;
        if (!used_.count(key)) fail(key_path(key), "unknown key");
    }
}

}  // namespace cutload::machine::detail
