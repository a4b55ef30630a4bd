// Internal to server: the prediction job pool. The runs and optimizations tables are the queue: a
// worker claims the oldest 'queued' run (then the oldest queued feed optimization), computes it
// outside any transaction and writes every result row, the final stock, the summary, alerts and
// webhook deliveries in one transaction with state 'done'. A crash at any point leaves the job
// 'queued' or 'running' with no results; start() re-queues 'running'.
#pragma once

#include "app/predict_run.hpp"
#include "common.hpp"
#include "db/jobs.hpp"
#include "metrics.hpp"

#include <filesystem>
#include <condition_variable>
#include <map>
#include <mutex>
#include <thread>

namespace cutload::server {

// A run's stored inputs (the log and program in its upload folder, the spec) as the use case's
// input; an nc_options object that is no longer valid is ApiError 400 naming the key.
app::RunInput run_input(const json& inputs, const std::filesystem::path& upload_dir, bool use_opencl);

// The final stock of base_run, from its bytes in the store (null without a base run).
force_model::StockPtr load_base_stock(db::Store& store, std::optional<std::int64_t> base_run);

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
