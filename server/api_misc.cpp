// Routes: /healthz, /metrics, /api/v1/openapi.json.
#include "core.hpp"
#include "db/alerts.hpp"
#include "db/jobs.hpp"
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
    core.route({"GET", "/healthz", std::nullopt}, [&core](Ctx& x) {
        const std::int64_t queued = core.session()->jobs().count(db::kRunQueue, {db::JobState::Queued});
        x.reply(200, {{"status", "ok"},
                      {"version", "0.1.0"},
                      {"schema_version", db::schema_version()},
                      {"queued", queued},
                      {"running", core.jobs->running()},
                      {"workers", core.opt.workers}});
    });
    core.route({"GET", "/metrics", Role::Read}, [&core](Ctx& x) {
        auto s = core.session();
        std::vector<Metrics::Queue> queues;
        for (const JobKind& k : core.jobs->kinds())
            queues.push_back({&k.metrics, static_cast<long>(s->jobs().count(k.queue, {db::JobState::Queued}))});
        const auto pending = s->webhooks().pending_count();
        std::string text = core.metrics.render(queues, core.jobs->running(), static_cast<long>(pending));
        text += series_cache_metrics(core.series_cache.stats());
        x.res.status = 200;
        x.res.set_content(text, "text/plain; version=0.0.4");
    });
    core.route({"GET", "/api/v1/openapi.json", std::nullopt}, [&core](Ctx& x) {
        x.res.status = 200;
        x.res.set_content(core.openapi, "application/json");
    });
}

}  // namespace cutload::server
