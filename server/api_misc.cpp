// Routes: /healthz, /metrics, /api/v1/openapi.json.
#include "server/core.hpp"
#include "server/jobs.hpp"

namespace cutload::server {

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
        x.res.status = 200;
        x.res.set_content(core.metrics.render(static_cast<long>(q.i64(0)), core.jobs->running(), static_cast<long>(d.i64(0))),
                          "text/plain; version=0.0.4");
    });
    core.route("GET", "/api/v1/openapi.json", std::nullopt, [](Ctx& x) {
        x.res.status = 200;
        x.res.set_content(openapi_json(), "application/json");
    });
}

}  // namespace cutload::server
