// Internal to server: routes declared once, with typed parameters.
//
// A RouteSpec says everything about a route but its handler: method, OpenAPI path template, its
// path and query parameters (type, required, default, allowed values or range, description), the
// role it needs and the kind of body it takes. The route wrapper (Core::route) validates every
// request against it before the handler runs, answering 400 naming the parameter; the OpenAPI
// document's parameters are generated from the same declarations (openapi_document), so code and
// document cannot disagree.
#pragma once

#include "common.hpp"

#include <functional>
#include <initializer_list>
#include <memory>
#include <optional>
#include <regex>
#include <string>
#include <variant>
#include <vector>

namespace cutload::server {

enum class ParamIn { Path, Query };
enum class ParamType { Integer, Number, Boolean, String };

struct Param {
    std::string name;
    ParamIn in = ParamIn::Query;
    ParamType type = ParamType::String;
    bool required = false;
    std::optional<json> fallback;                 // the default when not given
    std::optional<double> minimum, maximum;       // numbers, inclusive
    std::vector<std::string> allowed;             // strings: the only values accepted (OpenAPI enum)
    std::string pattern;                          // strings: ECMAScript regex the whole value matches
    std::string expect;                           // what a refused value is not: "an ISO 8601 UTC time (...)"
    std::string description;
    std::shared_ptr<const std::regex> compiled;   // pattern, compiled once

    // Chained refinements of a declaration.
    Param&& at_least(double lo) && { minimum = lo; return std::move(*this); }
    Param&& range(double lo, double hi) && { minimum = lo; maximum = hi; return std::move(*this); }
    Param&& or_else(json v) && { fallback = std::move(v); return std::move(*this); }
    Param&& one_of(std::vector<std::string> values) && { allowed = std::move(values); return std::move(*this); }
    Param&& matching(std::string regex, std::string what) && {
        pattern = std::move(regex);
        compiled = std::make_shared<const std::regex>(pattern);
        expect = std::move(what);
        return std::move(*this);
    }
    Param&& refused_as(std::string what) && { expect = std::move(what); return std::move(*this); }
};

// Declarations: a path parameter (always required) and query parameters of each type.
Param path_id(std::string name = "id");
Param query_int(std::string name, std::string description);
Param query_number(std::string name, std::string description);
Param query_bool(std::string name, std::string description);
Param query_string(std::string name, std::string description);

// What a route reads from the request body. OptionalJson: an empty body is allowed.
enum class Body { None, Json, OptionalJson, Multipart };

struct RouteSpec {
    RouteSpec(std::string method_, std::string path_, std::optional<Role> role_, std::vector<Param> params_ = {},
              Body body_ = Body::None, std::string multipart_hint_ = "")
        : method(std::move(method_)), path(std::move(path_)), role(role_), params(std::move(params_)), body(body_),
          multipart_hint(std::move(multipart_hint_)) {}

    std::string method;                 // GET, POST, PUT, DELETE
    std::string path;                   // OpenAPI template: /api/v1/runs/{id}
    std::optional<Role> role;           // nullopt: no key needed
    std::vector<Param> params;          // path parameters in template order, then query ones
    Body body = Body::None;
    std::string multipart_hint;         // Multipart: " with parts ...", for the error a wrong body gets
};

// A request's parameter values, checked and with defaults applied, in the order of the spec.
using ParamValue = std::variant<std::monostate, std::int64_t, double, bool, std::string>;

// Reads and checks the declared parameters; path values are the route pattern's captures in
// template order. Throws ApiError 400 naming the parameter.
std::vector<ParamValue> read_params(const RouteSpec& spec, const std::vector<std::string>& path_values,
                                    const std::function<std::optional<std::string>(const std::string&)>& query);

// The httplib pattern of a path template: each {name} captures that parameter's text.
std::string route_pattern(const RouteSpec& spec);

// The OpenAPI parameter objects of a route, in declaration order.
json openapi_parameters(const RouteSpec& spec);

// The OpenAPI document served: `base` (server/openapi.json: everything but parameters) with each
// declared route's parameters, the role it needs (x-cutload-role) or `security: []` when it needs
// no key. Operations missing from `base` are left out (the contract test names them).
json openapi_document(const json& base, const std::vector<RouteSpec>& routes);

// server/openapi.json as compiled in.
const std::string& openapi_base();

}  // namespace cutload::server
