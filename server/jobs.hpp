// Internal to server: the job pool and the kinds of job it runs.
//
// Each kind's table is its queue (db/jobs.hpp). A worker claims a job of the first kind in the
// registry that has one queued (runs before feed optimizations), computes it outside any
// transaction and lets the kind's handler write every result with state 'done' in one
// transaction. A crash at any point leaves the job 'queued' or 'running' with no results;
// start() re-queues 'running' jobs of every kind, up to an attempt cap: a job whose computing
// killed the server max_attempts times fails with the reason instead of looping. Claiming, dispatch, finishing, cancelling,
// re-queueing and metrics go through the registry, so a new kind is one JobKind in
// service_job_kinds() plus its handler (docs/architecture.md, "a new job kind").
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

// The work limits of `cutload serve` (--max-force-rows, --max-stock-cells, --max-job-memory-mb),
// checked at upload and again by the job.
app::WorkLimits work_limits(const ServerOptions& opt);

// The final stock of base_run, from its bytes in the store (null without a base run).
force_model::StockPtr load_base_stock(db::Store& store, std::optional<std::int64_t> base_run);

// What a handler gets for the job it computes.
struct JobContext {
    std::int64_t id;
    const std::atomic<bool>& cancel;   // set: throw force_model::Cancelled at the next step
    // Progress 0..1; written a few times a second at most (it is for people polling).
    std::function<void(double)> progress;
};

struct JobKind {
    std::string name;      // in logs: "run 12 done in 3.1 s"
    db::JobQueue queue;    // its table
    // Marks the next job running and returns its id; empty: the oldest queued one.
    std::function<std::optional<std::int64_t>(db::Session&)> claim;
    // Computes the job and stores its results with state done in one transaction. Returns what
    // the log line adds after "done in N s", or nullopt when the job's row was gone (deleted
    // meanwhile: nothing stored, nothing counted). Throws force_model::Cancelled when
    // ctx.cancel is set; any other exception fails the job with its message.
    std::function<std::optional<std::string>(JobContext& ctx)> handler;
    JobMetricNames metrics;
};

// The kinds `cutload serve` runs, in claim order: runs, then feed optimizations.
std::vector<JobKind> service_job_kinds(db::Store& store, const ServerOptions& opt, const std::filesystem::path& data_dir,
                                       Metrics& metrics, std::function<void()> on_alerts);

// How the pool runs jobs.
struct JobPoolOptions {
    int workers = 2;
    // Claims of one job before a server start stops re-queueing it: a job left running by a
    // process that died that often fails with the reason. A graceful stop's re-queue gives its
    // claim back, so only crashes count.
    int max_attempts = 3;
};

class Jobs {
public:
    Jobs(db::Store& store, JobPoolOptions opt, Metrics& metrics, std::vector<JobKind> kinds);
    ~Jobs();

    // Re-queues (or, at the attempt cap, fails) the jobs a dead server left running; starts the workers.
    void start();
    void notify();   // a job was queued
    // Sets the cancel flag of the job a worker computes; true if one was computing it.
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
    };
    void worker();
    std::optional<Claimed> claim();
    void run(const Claimed& job, const std::atomic<bool>& cancel);

    db::Store& store_;
    const JobPoolOptions opt_;
    Metrics& metrics_;
    const std::vector<JobKind> kinds_;

    mutable std::mutex mu_;
    std::condition_variable cv_, idle_cv_;
    bool stopping_ = false;
    std::uint64_t wake_seq_ = 0;   // bumped by notify(), so a sleeping worker sees new jobs
    std::atomic<bool> requeue_on_cancel_{false};
    std::map<std::pair<std::string_view, std::int64_t>, std::shared_ptr<std::atomic<bool>>> running_;
    std::vector<std::thread> threads_;
};

}  // namespace cutload::server
