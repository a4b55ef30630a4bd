// cutload serve: the HTTP service (see docs/api.md). SIGINT / SIGTERM stop it gracefully:
// running jobs get --drain-s seconds to finish and are re-queued otherwise.
#include "commands.hpp"
#include "server/server.hpp"

#include <csignal>
#include <cstdio>
#include <pthread.h>

namespace cutload::cli {
namespace {

struct ServeArgs {
    server::ServerOptions opt;
    std::string listen = "127.0.0.1:8080";
    double max_body_mb = 256;
    double cache_mb = 128;
    std::string device = "opencl";
};

void run_serve(ServeArgs& a) {
    split_listen(a.listen, "--listen", a.opt.host, a.opt.port);
    a.opt.max_body_bytes = static_cast<std::size_t>(a.max_body_mb * 1024 * 1024);
    a.opt.cache_bytes = static_cast<std::size_t>(a.cache_mb * 1024 * 1024);
    a.opt.use_opencl = a.device == "opencl";
    // Job threads run prediction after prediction: keep what one frees for the next. Before any
    // thread starts.
    if (a.opt.workers > 0 && !app::prepare_for_repeated_runs())
        std::fprintf(stderr, "cutload: note: the allocator kept its own thresholds (freed heap may be faulted in again)\n");

    // Signals go to this thread only, via sigwait: no work in a signal handler.
    sigset_t set = block_stop_signals();

    server::Server srv(a.opt);
    srv.start();
    std::printf("cutload: listening on http://%s:%d\n", a.opt.host.c_str(), srv.port());
    std::fflush(stdout);
    int sig = 0;
    sigwait(&set, &sig);
    std::printf("cutload: %s received, shutting down\n", sig == SIGINT ? "SIGINT" : "SIGTERM");
    std::fflush(stdout);
    srv.stop();
}

void add_serve(CLI::App& app) {
    auto a = std::make_shared<ServeArgs>();
    auto* sub = app.add_subcommand("serve", "Run the HTTP service: REST API, prediction jobs, alerts");
    sub->add_option("--listen", a->listen, "HOST:PORT to listen on (port 0: any free port)")->capture_default_str();
    add_store_options(*sub, a->opt);
    sub->add_option("--web", a->opt.web_dir, "Directory of static files served at / (default: none)");
    sub->add_option("--workers", a->opt.workers,
                    "Prediction jobs computed at once; 0: none, this server only answers the API (PostgreSQL, with cutload worker processes)")
        ->check(CLI::Range(0, 64))
        ->capture_default_str();
    sub->add_option("--http-threads", a->opt.http_threads, "Requests processed at once (idle and slow connections hold none)")
        ->check(CLI::Range(4, 1024))
        ->capture_default_str();
    sub->add_option("--header-timeout-s", a->opt.header_timeout_s,
                    "Seconds a connection may take to send its request line and headers (408 beyond)")
        ->check(CLI::Range(0.1, 3600.0))
        ->capture_default_str();
    sub->add_option("--keep-alive-s", a->opt.keep_alive_s, "Seconds an idle keep-alive connection is kept")
        ->check(CLI::Range(0.1, 3600.0))
        ->capture_default_str();
    sub->add_option("--body-read-timeout-s", a->opt.body_read_timeout_s,
                    "Seconds a request body may pause between bytes")
        ->check(CLI::Range(0.1, 3600.0))
        ->capture_default_str();
    sub->add_option("--body-timeout-s", a->opt.body_timeout_s, "Seconds a request body may take in all")
        ->check(CLI::Range(1.0, 86400.0))
        ->capture_default_str();
    sub->add_option("--max-waiting-connections", a->opt.max_waiting_connections,
                    "Connections waiting for their headers or idle; beyond, the longest waiting is closed")
        ->check(CLI::Range(8, 100000))
        ->capture_default_str();
    sub->add_option("--max-body-mb", a->max_body_mb, "Largest request body, MiB (413 beyond)")
        ->check(CLI::Range(0.001, 4096.0))
        ->capture_default_str();
    sub->add_option("--max-log-rows", a->opt.max_log_rows, "Most rows in an uploaded log (413 beyond)")->capture_default_str();
    add_job_options(*sub, a->opt, a->device);
    sub->add_option("--max-pending-jobs", a->opt.max_pending_jobs, "Most runs queued or running (429 beyond)")
        ->check(CLI::Range(1, 100000))
        ->capture_default_str();
    sub->add_option("--max-points", a->opt.max_points, "Largest max_points of forces/motion queries")
        ->check(CLI::Range(2, 1000000))
        ->capture_default_str();
    sub->add_option("--cache-mb", a->cache_mb, "Memory for decoded forces/motion chunks, MiB (least recently used out)")
        ->check(CLI::Range(0.0, 65536.0))
        ->capture_default_str();
    sub->add_flag("--anonymous-loopback-reads", a->opt.anonymous_loopback_reads,
                  "Allow GET requests without an API key from 127.0.0.1 / ::1 addressed to localhost, 127.0.0.1 or [::1]");
    sub->add_option("--webhook-backoff-s", a->opt.webhook_backoff_s, "First webhook retry delay (doubles per attempt)")
        ->check(CLI::Range(0.01, 3600.0))
        ->capture_default_str();
    sub->add_option("--webhook-max-attempts", a->opt.webhook_max_attempts, "Webhook attempts before giving up")
        ->check(CLI::Range(1, 100))
        ->capture_default_str();
    sub->callback([a] { run_serve(*a); });
}

const bool registered = register_command("serve", &add_serve);

}  // namespace
}  // namespace cutload::cli
