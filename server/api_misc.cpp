// Routes: /healthz, /metrics, /api/v1/openapi.json.
#include "core.hpp"
#include "jobs.hpp"

#include <fmt/format.h>

namespace cutload::server {
namespace {

std::string series_cache_metrics(const SeriesCache::Stats& st) {
    std::string out;
    auto metric = [&out](const char* name, const char* type, const char* help, auto value) {
        fmt::format_to(std::back_inserter(out), "# HELP {0} {1}\n# TYPE {0} {2}\n{0} {3}\n", name, help, type, value);
    };
    metric("cutload_series_cache_bytes", "gauge", "Decoded series data held in memory.", st.bytes);
    metric("cutload_series_cache_limit_bytes", "gauge", "Bound of the series cache (--cache-mb).", st.limit_bytes);
    metric("cutload_series_cache_entries", "gauge",
           "Chunks, chunk indexes, block name lists and whole-run answers cached.", st.entries);
    metric("cutload_series_cache_hits_total", "counter", "Series cache lookups answered from memory.", st.hits);
    metric("cutload_series_cache_misses_total", "counter", "Series cache lookups that read the database.", st.misses);
    metric("cutload_series_cache_evictions_total", "counter", "Entries dropped to stay within the bound.", st.evictions);
    return out;
}

}  // namespace

void add_misc_routes(Core& core) {
    core.route("GET", "/healthz", std::nullopt, [&core](Ctx& x) {
        auto c = core.pool.get();
        auto st = c->prepare("SELECT count(*) FROM runs WHERE state = 'queued'");
        st.step();
        x.reply(200, {{"status", "ok"},
                      {"version", "0.1.0"},
                      {"schema_version", db::schema_version()},
                      {"queued", st.i64(0)},
                      {"running", core.jobs->running()},
                      {"workers", core.opt.workers}});
    });
    core.route("GET", "/metrics", Role::Read, [&core](Ctx& x) {
        auto c = core.pool.get();
        auto q = c->prepare("SELECT count(*) FROM runs WHERE state = 'queued'");
        q.step();
        auto d = c->prepare("SELECT count(*) FROM webhook_deliveries WHERE state = 'pending'");
        d.step();
        auto o = c->prepare("SELECT count(*) FROM optimizations WHERE state = 'queued'");
        o.step();
        std::string text = core.metrics.render(static_cast<long>(q.i64(0)), core.jobs->running(), static_cast<long>(d.i64(0)),
                                               static_cast<long>(o.i64(0)));
        text += series_cache_metrics(core.series_cache.stats());
        x.res.status = 200;
        x.res.set_content(text, "text/plain; version=0.0.4");
    });
    core.route("GET", "/api/v1/openapi.json", std::nullopt, [](Ctx& x) {
        x.res.status = 200;
        x.res.set_content(openapi_json(), "application/json");
    });
}

}  // namespace cutload::server
