// `cutload worker`: the job pool of `cutload serve` without the API, on a store other processes
// share. It claims with leases (server/jobs.hpp) and answers GET /metrics and GET /healthz on its
// own small listener, so each process of a deployment is watched on its own (docs/deploy.md).
#include "server/server.hpp"

#include "db/jobs.hpp"
#include "db/store.hpp"
#include "jobs.hpp"
#include "metrics.hpp"

#include <fmt/format.h>
#include <httplib.h>
#include <spdlog/spdlog.h>

#include <sys/stat.h>

#include <filesystem>
#include <stdexcept>
#include <thread>

namespace cutload::server {
namespace fs = std::filesystem;

struct Worker::Impl {
    ServerOptions opt;
    std::unique_ptr<db::Store> store;
    Metrics metrics;
    std::unique_ptr<Jobs> jobs;
    httplib::Server http;
    std::thread listener;
    int bound_port = -1;
    bool started = false, stopped = false;
};

Worker::Worker(ServerOptions opt) : impl_(std::make_unique<Impl>()) {
    auto& w = *impl_;
    w.opt = std::move(opt);
    if (db::backend_of(w.opt.db_path) == db::Backend::Sqlite)
        throw std::runtime_error(fmt::format(
            "--db {}: a worker needs a store other processes share (postgresql://...); an SQLite file belongs to the one "
            "cutload serve that computes its jobs (serve --workers N)",
            w.opt.db_path));
    if (w.opt.data_dir.empty())
        throw std::runtime_error("--data-dir is required: the folder of uploads the cutload serve processes write (shared)");
    if (w.opt.workers < 1) throw std::runtime_error(fmt::format("--concurrency {}: at least 1", w.opt.workers));
    ::umask(static_cast<mode_t>(w.opt.file_umask & 0777u));
    if (!fs::is_directory(w.opt.data_dir))
        throw std::runtime_error(fmt::format("--data-dir {}: no such folder (the serve processes' --data-dir, shared)",
                                             w.opt.data_dir));
    w.store = db::Store::open(w.opt.db_path, db::Store::Open::MustExist);
    w.store->migrate();
    JobPoolOptions pool{w.opt.workers, w.opt.max_attempts};
    pool.shared_store = true;
    pool.lease_s = w.opt.lease_s;
    // Alerts a run raises are stored with their webhook deliveries; the serve processes deliver them.
    w.jobs = std::make_unique<Jobs>(*w.store, pool, w.metrics,
                                    service_job_kinds(*w.store, w.opt, w.opt.data_dir, w.metrics, [] {}));

    w.http.Get("/healthz", [&w](const httplib::Request&, httplib::Response& res) {
        res.set_content(fmt::format(R"({{"status":"ok","role":"worker","running":{},"workers":{}}})", w.jobs->running(),
                                    w.opt.workers),
                        "application/json");
    });
    w.http.Get("/metrics", [&w](const httplib::Request&, httplib::Response& res) {
        try {
            auto s = w.store->session();
            std::vector<Metrics::Queue> queues;
            for (const JobKind& k : w.jobs->kinds())
                queues.push_back({&k.metrics, static_cast<long>(s->jobs().count(k.queue, {db::JobState::Queued}))});
            res.set_content(w.metrics.render(queues, w.jobs->running(), 0), "text/plain; version=0.0.4");
        } catch (const std::exception& e) {
            res.status = 503;
            res.set_content(R"({"error":{"code":"store_unavailable","message":"the store did not answer"}})", "application/json");
            spdlog::warn("worker /metrics: {}", e.what());
        }
    });
}

Worker::~Worker() { stop(); }

void Worker::start() {
    auto& w = *impl_;
    if (w.opt.port >= 0) {
        w.bound_port = w.opt.port == 0 ? w.http.bind_to_any_port(w.opt.host)
                                       : (w.http.bind_to_port(w.opt.host, w.opt.port) ? w.opt.port : -1);
        if (w.bound_port < 0) throw std::runtime_error(fmt::format("cannot listen on {}:{}", w.opt.host, w.opt.port));
        w.listener = std::thread([&w] { w.http.listen_after_bind(); });
    }
    w.jobs->start();
    w.started = true;
    spdlog::info("cutload worker: {} job(s) at once on {}, leases of {} s{}", w.opt.workers,
                 db::printable_location(w.opt.db_path), w.opt.lease_s,
                 w.bound_port >= 0 ? fmt::format(", metrics on http://{}:{}/metrics", w.opt.host, w.bound_port) : "");
}

void Worker::stop() {
    auto& w = *impl_;
    if (w.stopped) return;
    w.stopped = true;
    w.jobs->stop(w.opt.drain_s);
    if (w.listener.joinable()) {
        w.http.stop();
        w.listener.join();
    }
}

int Worker::port() const { return impl_->bound_port; }

}  // namespace cutload::server
