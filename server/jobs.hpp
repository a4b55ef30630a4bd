// Internal to server: the job pool and the kinds of job it runs.
//
// Each kind's table is its queue (db/jobs.hpp). A worker claims a job of the first kind in the
// registry that has one queued (runs before feed optimizations), computes it outside any
// transaction and lets the kind's handler write every result with state 'done' in one
// transaction. A crash at any point leaves the job 'queued' or 'running' with no results.
// A claim is a lease (db::Lease) renewed while the job computes. On a store one server owns
// (SQLite), start() re-queues every 'running' job; on a shared store (PostgreSQL, several
// servers and `cutload worker`s) each pool re-queues the jobs whose lease ended, and a job whose
// claim is gone (cancelled or deleted by another process, or re-queued after a stall) is
// cancelled here at the next renewal. Only the claim that holds a job stores its results
// (JobContext::claim, db::JobRepository::holds). Either way a job whose computing killed its
// process max_attempts times fails with the reason instead of looping. Claiming, dispatch,
// finishing, cancelling, re-queueing and metrics go through the registry, so a new kind is one
// JobKind in service_job_kinds() plus its handler (docs/architecture.md, "a new job kind").
#pragma once

#include "app/predict_run.hpp"
#include "common.hpp"
#include "db/jobs.hpp"
#include "metrics.hpp"

#include <atomic>
#include <condition_variable>
#include <filesystem>
#include <functional>
#include <map>
#include <mutex>
#include <thread>

namespace cutload::server {

// A run's stored inputs (the log and program in its upload folder, the spec) as the use case's
// input; an nc_options object that is no longer valid is ApiError 400 naming the key.
app::RunInput run_input(const json& inputs, const std::filesystem::path& upload_dir, bool use_opencl);

// The machine files of a run's inputs.kinematics in its upload folder, named in messages by the
// parts they were uploaded as ("part kinematics", "part kinematics_errors"): a client sees its
// own names, never the server's paths, at upload and in a failed job's error alike.
app::MachineFiles kinematics_files(const std::filesystem::path& upload_dir, const json& kinematics);

// The work limits of `cutload serve` (--max-force-rows, --max-stock-cells, --max-job-memory-mb),
// checked at upload and again by the job.
app::WorkLimits work_limits(const ServerOptions& opt);

// The final stock of base_run, from its bytes in the store (null without a base run).
force_model::StockPtr load_base_stock(db::Store& store, std::optional<std::int64_t> base_run);

// Where a run keeps its stock checkpoints (app/checkpoints.hpp): beside its uploads, so they go
// with its folder.
inline std::filesystem::path checkpoints_dir(const std::filesystem::path& upload_dir) { return upload_dir / "checkpoints"; }

// What a handler gets for the job it computes.
struct JobContext {
    std::int64_t id;
    // The claim's token: the handler stores its results in a transaction that first checks the
    // claim still holds the job (db::JobRepository::holds), and stores nothing otherwise.
    std::string claim;
    const std::atomic<bool>& cancel;   // set: throw force_model::Cancelled at the next step
    // Progress 0..1; written a few times a second at most (it is for people polling).
    std::function<void(double)> progress;
};

struct JobKind {
    std::string name;      // in logs: "run 12 done in 3.1 s"
    db::JobQueue queue;    // its table
    // Marks the next job running under the lease and returns its id; empty: the oldest queued one.
    std::function<std::optional<std::int64_t>(db::Session&, const db::Lease&)> claim;
    // Computes the job and stores its results with state done in one transaction. Returns what
    // the log line adds after "done in N s", or nullopt when the claim no longer held the job
    // (deleted or re-queued meanwhile: nothing stored, nothing counted). Throws force_model::Cancelled when
    // ctx.cancel is set; any other exception fails the job with its message.
    std::function<std::optional<std::string>(JobContext& ctx)> handler;
    JobMetricNames metrics;
};

// The kinds `cutload serve` runs, in claim order: runs, then feed optimizations.
std::vector<JobKind> service_job_kinds(db::Store& store, const ServerOptions& opt, const std::filesystem::path& data_dir,
                                       Metrics& metrics, std::function<void()> on_alerts);

// How the pool runs jobs.
struct JobPoolOptions {
    int workers = 2;       // jobs computed at once; 0: none (a server that only answers the API)
    // Claims of one job before it is no longer re-queued: a job left running by a process that
    // died that often fails with the reason. A graceful stop's re-queue gives its claim back, so
    // only crashes count.
    int max_attempts = 3;
    // Other processes claim from the same store (PostgreSQL): jobs are re-queued when their lease
    // ends, not all at start, and leases are renewed every lease_s / 3.
    bool shared_store = false;
    double lease_s = 30;
    std::string name = "cutload serve";   // in the re-queue error: who died
};

class Jobs {
public:
    Jobs(db::Store& store, JobPoolOptions opt, Metrics& metrics, std::vector<JobKind> kinds);
    ~Jobs();

    // Re-queues (or, at the attempt cap, fails) the jobs a dead process left running (on a shared
    // store: those whose lease ended, and from then on every lease_s / 3); starts the workers.
    void start();
    void notify();   // a job was queued
    // Sets the cancel flag of the job a worker here computes; on a shared store, a job another
    // process computes is cancelled in the store (it stops at its next lease renewal). True if
    // the job was running.
    bool cancel_running(const db::JobQueue& queue, std::int64_t id);
    // Waits up to timeout_s until no worker computes the job; true once none does.
    bool wait_released(const db::JobQueue& queue, std::int64_t id, double timeout_s);
    // Stops claiming; waits up to drain_s for running jobs, then cancels them back to 'queued'
    // and joins the workers (each stops at its job's next cancel check).
    void stop(double drain_s);
    long running() const;
    const std::vector<JobKind>& kinds() const { return kinds_; }

private:
    struct Claimed {
        const JobKind* kind;
        std::int64_t id;
        std::string token;
    };
    struct Running {
        std::shared_ptr<std::atomic<bool>> cancel;
        int misses = 0;      // renewals in a row that did not find it running under this process
        bool lost = false;   // its claim is gone from the store (two renewals did not find it)
    };
    void worker();
    std::optional<Claimed> claim();
    void run(const Claimed& job, const std::atomic<bool>& cancel);
    std::string lease_until() const;   // a lease taken or renewed now ends then
    db::Lease next_lease();
    void requeue(bool expired_only);
    void keeper();   // renews leases, cancels lost claims, re-queues expired ones
    void listener(); // wakes the workers when another process queues a job

    db::Store& store_;
    const JobPoolOptions opt_;
    Metrics& metrics_;
    const std::vector<JobKind> kinds_;

    mutable std::mutex mu_;
    std::condition_variable cv_, idle_cv_;
    bool stopping_ = false;
    bool workers_joined_ = false;   // after a stop: the keeper ends
    std::uint64_t wake_seq_ = 0;   // bumped by notify(), so a sleeping worker sees new jobs
    std::atomic<bool> requeue_on_cancel_{false};
    std::map<std::pair<std::string_view, std::int64_t>, Running> running_;
    std::vector<std::thread> threads_;
    std::thread keeper_, listener_;
    const std::string token_prefix_;   // this pool's claims: host:pid:random/
    std::uint64_t claims_ = 0;
};

}  // namespace cutload::server
