#include "route.hpp"

#include <fmt/format.h>

#include <cmath>
#include <regex>

namespace cutload::server {
namespace {

const char* where(ParamIn in) { return in == ParamIn::Path ? "path" : "query"; }

const char* type_name(ParamType t) {
    switch (t) {
        case ParamType::Integer: return "integer";
        case ParamType::Number: return "number";
        case ParamType::Boolean: return "boolean";
        case ParamType::String: return "string";
    }
    return "string";
}

// "a", "a or b", "a, b or c".
std::string alternatives(const std::vector<std::string>& v) {
    std::string s;
    for (std::size_t i = 0; i < v.size(); ++i) s += (i == 0 ? "" : i + 1 == v.size() ? " or " : ", ") + v[i];
    return s;
}

Param declared(std::string name, ParamType type, std::string description) {
    Param p;
    p.name = std::move(name);
    p.type = type;
    p.description = std::move(description);
    return p;
}

[[noreturn]] void refuse(const Param& p, const std::string& why) {
    bad_request(fmt::format("{} parameter {}: {}", where(p.in), p.name, why));
}

void check_range(const Param& p, double v, const std::string& text) {
    const bool low = p.minimum && v < *p.minimum, high = p.maximum && v > *p.maximum;
    if (!low && !high) return;
    // fmt writes a whole bound without a decimal point: "outside 1..1000".
    if (p.minimum && p.maximum) refuse(p, fmt::format("{} is outside {}..{}", text, *p.minimum, *p.maximum));
    if (low) refuse(p, fmt::format("{} is below {}", text, *p.minimum));
    refuse(p, fmt::format("{} is above {}", text, *p.maximum));
}

ParamValue parse_value(const Param& p, const std::string& s) {
    switch (p.type) {
        case ParamType::Integer: {
            std::int64_t v = 0;
            try {
                std::size_t used = 0;
                v = std::stoll(s, &used);
                if (used != s.size()) throw std::invalid_argument(s);
            } catch (const std::exception&) {
                refuse(p, fmt::format("'{}' is not an integer", s));
            }
            check_range(p, static_cast<double>(v), std::to_string(v));
            return v;
        }
        case ParamType::Number: {
            double v = 0;
            try {
                std::size_t used = 0;
                v = std::stod(s, &used);
                if (used != s.size() || !std::isfinite(v)) throw std::invalid_argument(s);
            } catch (const std::exception&) {
                refuse(p, fmt::format("'{}' is not a number", s));
            }
            check_range(p, v, s);
            return v;
        }
        case ParamType::Boolean:
            if (s == "true" || s == "1") return true;
            if (s == "false" || s == "0") return false;
            refuse(p, fmt::format("'{}' is not true or false", s));
        case ParamType::String:
            if (!p.allowed.empty() && std::find(p.allowed.begin(), p.allowed.end(), s) == p.allowed.end())
                refuse(p, fmt::format("'{}' is not {}", s, p.expect.empty() ? alternatives(p.allowed) : p.expect));
            if (p.compiled && !std::regex_match(s, *p.compiled))
                refuse(p, fmt::format("'{}' is not {}", s, p.expect.empty() ? "of the form " + p.pattern : p.expect));
            return s;
    }
    return std::monostate{};
}

ParamValue fallback_value(const Param& p) {
    if (!p.fallback) return std::monostate{};
    const json& d = *p.fallback;
    switch (p.type) {
        case ParamType::Integer: return d.get<std::int64_t>();
        case ParamType::Number: return d.get<double>();
        case ParamType::Boolean: return d.get<bool>();
        case ParamType::String: return d.get<std::string>();
    }
    return std::monostate{};
}

}  // namespace

Param path_id(std::string name) {
    Param p = declared(std::move(name), ParamType::Integer, "");
    p.in = ParamIn::Path;
    p.required = true;
    p.minimum = 1;
    return p;
}

Param query_int(std::string name, std::string description) {
    return declared(std::move(name), ParamType::Integer, std::move(description));
}
Param query_number(std::string name, std::string description) {
    return declared(std::move(name), ParamType::Number, std::move(description));
}
Param query_bool(std::string name, std::string description) {
    return declared(std::move(name), ParamType::Boolean, std::move(description));
}
Param query_string(std::string name, std::string description) {
    return declared(std::move(name), ParamType::String, std::move(description));
}

std::vector<ParamValue> read_params(const RouteSpec& spec, const std::vector<std::string>& path_values,
                                    const std::function<std::optional<std::string>(const std::string&)>& query) {
    std::vector<ParamValue> out;
    out.reserve(spec.params.size());
    std::size_t next_path = 0;
    for (const Param& p : spec.params) {
        std::optional<std::string> text;
        if (p.in == ParamIn::Path) {
            if (next_path < path_values.size()) text = path_values[next_path];
            ++next_path;
        } else {
            text = query(p.name);
        }
        if (!text) {
            if (p.required) refuse(p, "required");
            out.push_back(fallback_value(p));
            continue;
        }
        out.push_back(parse_value(p, *text));
    }
    return out;
}

std::string route_pattern(const RouteSpec& spec) {
    static const std::regex placeholder(R"(\{([a-z_]+)\})");
    std::string out;
    auto rest = spec.path.cbegin();
    for (std::sregex_iterator it(spec.path.begin(), spec.path.end(), placeholder), end; it != end; ++it) {
        out.append(rest, spec.path.cbegin() + it->position());
        const std::string name = (*it)[1].str();
        const auto p = std::find_if(spec.params.begin(), spec.params.end(),
                                    [&](const Param& q) { return q.in == ParamIn::Path && q.name == name; });
        if (p == spec.params.end())
            throw std::logic_error(fmt::format("{} {}: path parameter {} is not declared", spec.method, spec.path, name));
        // Ids are digits: other text is no such resource (404), as for any unknown path.
        out += p->type == ParamType::Integer ? "([0-9]+)" : "([^/]+)";
        rest = spec.path.cbegin() + it->position() + it->length();
    }
    out.append(rest, spec.path.cend());
    return out;
}

json openapi_parameters(const RouteSpec& spec) {
    json out = json::array();
    for (const Param& p : spec.params) {
        auto bound = [&](double v) { return p.type == ParamType::Integer ? json(static_cast<std::int64_t>(v)) : json(v); };
        json schema{{"type", type_name(p.type)}};
        if (p.minimum) schema["minimum"] = bound(*p.minimum);
        if (p.maximum) schema["maximum"] = bound(*p.maximum);
        if (!p.allowed.empty()) schema["enum"] = p.allowed;
        if (!p.pattern.empty()) schema["pattern"] = p.pattern;
        if (p.fallback) schema["default"] = *p.fallback;
        json o{{"name", p.name}, {"in", where(p.in)}, {"required", p.required}, {"schema", schema}};
        if (!p.description.empty()) o["description"] = p.description;
        out.push_back(std::move(o));
    }
    return out;
}

json openapi_document(const json& base, const std::vector<RouteSpec>& routes) {
    json doc = base;
    for (const RouteSpec& r : routes) {
        std::string method = r.method;
        for (char& ch : method) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
        if (!doc["paths"].contains(r.path) || !doc["paths"][r.path].contains(method)) continue;
        json& op = doc["paths"][r.path][method];
        const json params = openapi_parameters(r);
        if (params.empty())
            op.erase("parameters");
        else
            op["parameters"] = params;
        if (r.role) {
            op["x-cutload-role"] = role_name(*r.role);
            op.erase("security");
        } else {
            op["security"] = json::array();
            op.erase("x-cutload-role");
        }
    }
    return doc;
}

}  // namespace cutload::server
