// Internal to server: what the route groups share (options, store, metrics, jobs, webhooks) and
// the route registration that applies auth, parameter checks, error mapping and metrics to every
// handler.
#pragma once

#include "common.hpp"
#include "http_gate.hpp"
#include "metrics.hpp"
#include "route.hpp"
#include "series.hpp"

#include <httplib.h>

#include <atomic>
#include <filesystem>
#include <functional>
#include <string_view>
#include <thread>

namespace cutload::server {

class Jobs;
class LiveRuns;
class Webhooks;

// One request to a declared route, its parameters checked (route.hpp).
struct Ctx {
    const httplib::Request& req;
    httplib::Response& res;
    const RouteSpec& route;
    std::vector<ParamValue> values;   // route.params' values, defaults applied
    Role role;
    std::string actor;   // "clk_1234ab" (the key's prefix) or "anonymous"

    // The path parameter {id}.
    std::int64_t id() const;
    // A declared parameter's value (its default when not given; nullopt when neither). Asking for
    // an undeclared name, or as another type than declared, is a programming error (logic_error).
    std::optional<std::string> param(std::string_view name) const;
    std::optional<double> param_double(std::string_view name) const;
    std::optional<std::int64_t> param_int(std::string_view name) const;
    std::optional<bool> param_bool(std::string_view name) const;
    // Whether the request gave the parameter (a default does not count).
    bool given(std::string_view name) const;
    // Accept: text/csv, or format=csv on a route that declares format.
    bool wants_csv() const;
    // The JSON body (400 bad_json when it is not JSON); nullopt for an empty body on a route whose
    // body is optional.
    std::optional<json> json_body() const;
    void reply(int status, const json& body);

private:
    const ParamValue& value_of(std::string_view name, ParamType type) const;
};

using Handler = std::function<void(Ctx&)>;

struct Core {
    explicit Core(ServerOptions o);
    ~Core();

    ServerOptions opt;
    std::filesystem::path data_dir;
    std::unique_ptr<db::Store> store;   // opened by the Server (after the lock), absent otherwise
    GatedHttpServer http;
    Metrics metrics;
    SeriesCache series_cache;
    std::unique_ptr<Jobs> jobs;
    std::unique_ptr<Webhooks> hooks;
    std::unique_ptr<LiveRuns> live;
    std::vector<RouteSpec> routes;
    std::string openapi;   // the document served, built from `routes` once all are declared
    // Set as the server stops: work a request does on its own thread (a recomputed window) stops.
    std::atomic<bool> stopping{false};
    int lock_fd = -1;

    db::SessionLease session() { return store->session(); }

    // Declares a route and binds its handler.
    void route(RouteSpec spec, Handler h);

    // Decides on a request from its headers alone, before any body is read: the route it is for,
    // the key and role that route needs, the announced body's size. False when refused (`res`
    // then holds the answer and the connection closes without reading the body).
    bool admit(const httplib::Request& req, httplib::Response& res);

private:
    Role authorize(const httplib::Request& req, Role need, std::string* actor);

    struct Matcher {
        std::shared_ptr<const RouteSpec> spec;
        std::string literal;   // the path up to its first parameter: a cheap test before the regex
        std::regex pattern;
    };
    std::vector<Matcher> matchers_;   // the routes as httplib matches them, in the same order
};

// Every route group, in the order they are declared.
void add_all_routes(Core& c);

// A finished run (404 unknown, 409 `not_done` otherwise), and its stored program comparison
// (404 `no_program` for a run uploaded without an NC program).
RunRef require_done(db::Session& s, std::int64_t id);
json require_program(db::Session& s, std::int64_t id);

void add_library_routes(Core& c);
void add_run_routes(Core& c);
void add_program_routes(Core& c);
void add_measurement_routes(Core& c);
void add_calibration_routes(Core& c);
void add_alert_routes(Core& c);
void add_misc_routes(Core& c);
void add_view_routes(Core& c);
void add_live_routes(Core& c);

}  // namespace cutload::server
