// cutload worker: computes the jobs of a PostgreSQL store beside `cutload serve --workers 0`
// processes (docs/deploy.md). SIGINT / SIGTERM stop it gracefully: running jobs get --drain-s
// seconds to finish and are re-queued otherwise. A worker killed outright has its jobs
// re-queued by the other processes once their leases (--lease-s) end.
#include "commands.hpp"
#include "server/server.hpp"

#include <csignal>
#include <cstdio>
#include <pthread.h>

namespace cutload::cli {
namespace {

struct WorkerArgs {
    server::ServerOptions opt;
    std::string metrics_listen;
    std::string device = "opencl";
};

void run_worker(WorkerArgs& a) {
    a.opt.port = -1;
    if (!a.metrics_listen.empty()) split_listen(a.metrics_listen, "--metrics-listen", a.opt.host, a.opt.port);
    a.opt.use_opencl = a.device == "opencl";
    // Prediction after prediction: keep what one frees for the next. Before any thread starts.
    if (!app::prepare_for_repeated_runs())
        std::fprintf(stderr, "cutload: note: the allocator kept its own thresholds (freed heap may be faulted in again)\n");

    sigset_t set = block_stop_signals();

    server::Worker worker(a.opt);
    worker.start();
    if (worker.port() >= 0) std::printf("cutload: worker metrics on http://%s:%d/metrics\n", a.opt.host.c_str(), worker.port());
    std::printf("cutload: worker computing up to %d job(s) at once\n", a.opt.workers);
    std::fflush(stdout);
    int sig = 0;
    sigwait(&set, &sig);
    std::printf("cutload: %s received, shutting down\n", sig == SIGINT ? "SIGINT" : "SIGTERM");
    std::fflush(stdout);
    worker.stop();
}

void add_worker(CLI::App& app) {
    auto a = std::make_shared<WorkerArgs>();
    a->opt.workers = 1;
    a->opt.db_path.clear();
    auto* sub = app.add_subcommand(
        "worker", "Compute prediction and optimization jobs from a PostgreSQL store shared with cutload serve (no API)");
    add_store_options(*sub, a->opt);
    sub->get_option("--db")->required();
    sub->get_option("--data-dir")->required();
    sub->add_option("--concurrency", a->opt.workers, "Jobs computed at once")->check(CLI::Range(1, 64))->capture_default_str();
    sub->add_option("--metrics-listen", a->metrics_listen,
                    "HOST:PORT serving GET /metrics and GET /healthz of this worker (default: none; port 0: any free port)");
    add_job_options(*sub, a->opt, a->device);
    sub->callback([a] { run_worker(*a); });
}

const bool registered = register_command("worker", &add_worker);

}  // namespace
}  // namespace cutload::cli
