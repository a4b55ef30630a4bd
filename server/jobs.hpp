// Internal to server: the prediction job pool. The runs and optimizations tables are the queue: a
// worker claims the oldest 'queued' run (then the oldest queued feed optimization), computes it
// outside any transaction and writes every result row, the final stock, the summary, alerts and
// webhook deliveries in one transaction with state 'done'. A crash at any point leaves the job
// 'queued' or 'running' with no results; start() re-queues 'running'.
#pragma once

#include "force_model/force_model.hpp"
#include "motion_io/motion_io.hpp"
#include "common.hpp"
#include "db/jobs.hpp"
#include "metrics.hpp"

#include <filesystem>
#include <condition_variable>
#include <map>
#include <mutex>
#include <thread>

namespace cutload::server {

// The run's stored log, read and repaired with the options it was uploaded with.
motion_io::MotionModel ingest_run_log(const json& inputs, const std::filesystem::path& upload_dir);

// The final stock of base_run (null without one); `scratch_dir` holds a temporary file meanwhile.
force_model::StockPtr load_base_stock(db::Store& store, std::optional<std::int64_t> base_run,
                                      const std::filesystem::path& scratch_dir);

class Jobs {
public:
    Jobs(db::Store& store, const ServerOptions& opt, std::filesystem::path data_dir, Metrics& metrics,
         std::function<void()> on_alerts);
    ~Jobs();

    void start();
    void notify();                        // a run was queued
    enum class Kind { Run, Optimization };
    bool cancel_running(Kind kind, std::int64_t id);   // true if a worker was computing it
    // Stops claiming; waits up to drain_s for running jobs, then cancels them back to 'queued'.
    void stop(double drain_s);
    long running() const;

private:
    void worker();
    struct Job {
        Kind kind;
        std::int64_t id;
    };
    std::optional<Job> claim();
    void execute(std::int64_t id, const std::atomic<bool>& cancel);
    void optimize(std::int64_t id, const std::atomic<bool>& cancel);
    void finish(Kind kind, std::int64_t id, db::JobState state, const std::string& error);

    db::Store& store_;
    const ServerOptions& opt_;
    std::filesystem::path data_dir_;
    Metrics& metrics_;
    std::function<void()> on_alerts_;

    mutable std::mutex mu_;
    std::condition_variable cv_, idle_cv_;
    bool stopping_ = false;
    std::uint64_t wake_seq_ = 0;   // bumped by notify(), so a sleeping worker sees new runs
    std::atomic<bool> requeue_on_cancel_{false};
    std::map<std::pair<Kind, std::int64_t>, std::shared_ptr<std::atomic<bool>>> running_;
    std::vector<std::thread> threads_;
};

}  // namespace cutload::server
