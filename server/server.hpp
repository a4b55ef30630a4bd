// Public interface of server: cutload's HTTP service (REST API under /api/v1, job workers,
// threshold alerts and webhook delivery) on an embedded SQLite store.
#pragma once

#include <cstddef>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace cutload::server {

struct ServerOptions {
    std::string host = "127.0.0.1";
    int port = 8080;                       // 0: any free port (see Server::port())
    std::string db_path = "cutload.db";      // SQLite file, or postgresql://user:password@host/db
    std::string data_dir;                  // uploads; empty: "<db_path>.data" next to an SQLite db
                                           // (required with PostgreSQL)
    std::string web_dir;                   // static files at "/"; empty: none
    int workers = 2;                       // prediction jobs run at once; 0: none (API only,
                                           // `cutload worker`s compute; PostgreSQL)
    int http_threads = 64;                 // requests processed at once (idle or slow connections hold none)
    std::size_t max_body_bytes = 256u << 20;
    // Slow clients: a connection's request line and headers must arrive within header_timeout_s of
    // its first byte (of the connection, for a new one), else 408; an idle keep-alive connection is
    // closed after keep_alive_s; a body may pause body_read_timeout_s between bytes and take
    // body_timeout_s in all. Connections waiting for headers or idle are at most
    // max_waiting_connections: beyond, the one waiting longest is closed.
    double header_timeout_s = 10;
    double keep_alive_s = 5;
    double body_read_timeout_s = 10;
    double body_timeout_s = 600;
    int max_waiting_connections = 512;
    std::size_t max_header_bytes = 64u << 10;   // request line + headers; 431 beyond
    std::size_t max_log_rows = 20'000'000;
    // Work limits (app::WorkLimits; docs/api.md, "Work limits"): a run whose estimated work passes
    // one is refused at upload (400 too_much_work) and stopped by the engine should it pass the rows.
    double max_force_rows = 2e8;   // as app::WorkLimits
    // A run expecting more force rows stores envelopes from the first pyramid level that fits
    // (docs/api.md, "Long runs"); 0: every row, whatever the run's length.
    double max_raw_rows = 4e6;
    // Stock checkpoints a run keeps for windows recomputed later (docs/api.md, "Recomputed
    // windows"): at most one per this much motion and 8 a run; 0: none.
    double checkpoint_every_s = 60;
    double max_stock_cells = 20e6;
    double max_job_memory_mb = 3000;
    int max_pending_jobs = 64;             // queued + running; beyond: 429
    int max_points = 20000;                // cap of forces/motion max_points
    std::size_t cache_bytes = 128u << 20;  // decoded series chunks kept in memory (LRU)
    bool anonymous_loopback_reads = false; // GET without a key from 127.0.0.1 / ::1
    bool use_opencl = true;                // force engine device
    double drain_s = 10;                   // on stop: running jobs get this long, then re-queue
    int max_attempts = 3;                  // claims of one job across server crashes; then 'failed'
    // A job's claim is held this long unless renewed (every lease_s / 3): on PostgreSQL, a job
    // whose process died is re-queued by another process this long after its last renewal.
    double lease_s = 30;
    // The process umask while serving: the database, its WAL, uploads and their folders are
    // created without these permission bits (077: owner only, files 0600, folders 0700). The
    // database files that exist already are brought to the same mode at start.
    unsigned file_umask = 077;
    double webhook_backoff_s = 2;          // first retry delay; doubles per attempt
    int webhook_max_attempts = 6;
    double webhook_timeout_s = 5;
    // A run whose blocks exceed the run's own limits (the engine's flags) raises an alert without
    // any threshold set up: critical for a collision (rapid in material, holder contact), else a
    // warning. Flags an enabled flag threshold applying to the run covers are left to it.
    bool limit_alerts = true;
};

// `cutload worker`: computes the jobs of a PostgreSQL store that `cutload serve` processes answer
// for (docs/deploy.md); no API. Its claims are leases it renews while it computes; a worker that
// dies has its jobs re-queued by the other processes once the lease ends. Uses db_path, data_dir
// (the serve processes' uploads, shared), workers, use_opencl, the work limits, max_raw_rows,
// limit_alerts, max_attempts, lease_s and drain_s; `host`/`port` serve GET /metrics and
// GET /healthz (port -1: no listener).
class Worker {
public:
    explicit Worker(ServerOptions opt);   // opens and migrates the store; refuses SQLite
    ~Worker();                            // stop() if still running
    Worker(const Worker&) = delete;
    Worker& operator=(const Worker&) = delete;
    void start();
    // Graceful: no new claims, running jobs get drain_s to finish, then are re-queued.
    void stop();
    int port() const;   // of the metrics listener; -1 without one

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

class Server {
public:
    explicit Server(ServerOptions opt);   // opens and migrates the db, re-queues interrupted jobs
    ~Server();                            // stop() if still running
    Server(const Server&) = delete;
    Server& operator=(const Server&) = delete;

    // Binds, starts workers and the HTTP listener in background threads; returns once listening.
    void start();
    // Graceful: stops accepting, lets running jobs finish within drain_s, re-queues the rest.
    void stop();
    // Blocks until stop() is called from another thread (or a signal handler's thread).
    void wait();
    int port() const;

    // The routes this server answers, as (METHOD, OpenAPI path template) pairs.
    std::vector<std::pair<std::string, std::string>> routes() const;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

enum class Role { Read = 0, Write = 1, Admin = 2 };
Role parse_role(const std::string& s);          // throws std::invalid_argument
const char* role_name(Role r);

// The store location (an SQLite path or a postgresql:// URL, db/store.hpp) as output may show
// it: a URL's password replaced by "***".
std::string printable_db(const std::string& db_path);

// Creates an API key in the database (migrating it if new) and returns the key; only its
// SHA-256 is stored.
std::string create_api_key(const std::string& db_path, Role role, const std::string& name = "");

// An API key as `cutload keys list` shows it; the key itself is never stored.
struct ApiKeyInfo {
    std::string prefix;   // first 10 characters of the key
    Role role = Role::Read;
    std::string name;
    std::string created_at;
    std::optional<std::string> last_used_at;   // to the minute: updated at most once a minute
    std::optional<std::string> revoked_at;
};

// Keys of an existing database, oldest first. Throws std::invalid_argument when there is no
// database at db_path.
std::vector<ApiKeyInfo> list_api_keys(const std::string& db_path);

// Revokes the one key whose prefix starts with prefix_or_key (or that is this whole key); a
// revoked key is answered 401 from the next request on. Throws std::invalid_argument when no key
// or several keys match. Revoking a revoked key changes nothing (*already_revoked tells).
ApiKeyInfo revoke_api_key(const std::string& db_path, const std::string& prefix_or_key, bool* already_revoked = nullptr);

// The OpenAPI 3 document served at /api/v1/openapi.json.
const std::string& openapi_json();

}  // namespace cutload::server
