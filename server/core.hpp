// Internal to server: what the route groups share (options, pool, metrics, jobs, webhooks) and
// the route registration helper that applies auth, error mapping and metrics to every handler.
#pragma once

#include "common.hpp"
#include "metrics.hpp"
#include "series.hpp"

#include <httplib.h>

#include <atomic>
#include <filesystem>
#include <functional>
#include <thread>

namespace cutload::server {

class Jobs;
class Webhooks;

struct Ctx {
    const httplib::Request& req;
    httplib::Response& res;
    Role role;
    std::string actor;   // "clk_1234ab" (the key's prefix) or "anonymous"

    // The n-th numeric path parameter ({id}) of the route.
    std::int64_t id(std::size_t n = 1) const;
    bool wants_csv() const;
    void reply(int status, const json& body);
    // Query parameter helpers: 400 naming the parameter on a bad value.
    std::optional<std::string> param(const char* name) const;
    std::optional<double> param_double(const char* name) const;
    std::optional<std::int64_t> param_int(const char* name) const;
    std::optional<bool> param_bool(const char* name) const;
};

using Handler = std::function<void(Ctx&)>;

struct Core {
    explicit Core(ServerOptions o);
    ~Core();

    ServerOptions opt;
    std::filesystem::path data_dir;
    DbPool pool;
    httplib::Server http;
    Metrics metrics;
    SeriesCache series_cache;
    std::unique_ptr<Jobs> jobs;
    std::unique_ptr<Webhooks> hooks;
    std::vector<std::pair<std::string, std::string>> route_list;
    int lock_fd = -1;

    // path is the OpenAPI template; "{name}" segments match digits. need: nullopt = no key needed.
    void route(const std::string& method, const std::string& path, std::optional<Role> need, Handler h);

private:
    Role authorize(const httplib::Request& req, Role need, std::string* actor);
};

// A finished run (404 unknown, 409 `not_done` otherwise), and its stored program comparison
// (404 `no_program` for a run uploaded without an NC program).
RunRef require_done(db::Connection& c, std::int64_t id);
json require_program(db::Connection& c, std::int64_t id);

void add_library_routes(Core& c);
void add_run_routes(Core& c);
void add_program_routes(Core& c);
void add_measurement_routes(Core& c);
void add_calibration_routes(Core& c);
void add_alert_routes(Core& c);
void add_misc_routes(Core& c);
void add_view_routes(Core& c);

}  // namespace cutload::server
