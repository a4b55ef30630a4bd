// Internal to server: live runs (docs/live.md, "Live runs in the service"). Each live run has a
// worker thread that reads its source through app::run_live and stores what comes as it comes:
// force rows in chunks and the run's status (connection, lag) in one transaction per batch; each
// completed block with the alerts it raises (and their webhook deliveries) in one transaction.
// When the run closes (program end, stop, idle) its results are written as any run's and the live
// record is closed, in one transaction: the run is then an ordinary finished run.
//
// A service that dies during a live run leaves a 'running' run with an open live record;
// recover() (before the job workers start, which would re-queue 'running' runs) closes each as
// a finished run from what was stored, with the restart marked as a gap: never half-written,
// nothing stored twice (the blocks' alerts were raised when they were stored).
#pragma once

#include "app/live_run.hpp"
#include "common.hpp"
#include "db/runs.hpp"

#include <atomic>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <thread>

namespace cutload::server {

// The live status the API shows: from the worker while it runs, else from the store.
struct LiveState {
    bool open = false;
    std::string connection;   // connecting, connected, disconnected, closed
    double lag_ms = 0, machine_t_s = 0;
    std::int64_t rows = 0, alerts = 0;
    json gaps = json::array();
    std::optional<std::string> end_reason;
};

class LiveRuns {
public:
    LiveRuns(db::Store& store, const ServerOptions& opt, std::function<void()> on_alerts);
    ~LiveRuns();   // stop_all()

    // Creates the run (state running, live record open) and starts its worker. `source` is the
    // live source's address (shdr://..., http://...); `source_json` is stored as given.
    std::int64_t start(const db::NewRun& run, const json& source_json, const std::string& source, app::LiveOptions opt);
    // Asks the run's worker to close the run; false when no worker runs it (not live, or closed).
    bool stop(std::int64_t run_id);
    // Closes every live run (service shutdown) as a finished run, and waits for the workers.
    void stop_all();
    // Closes the runs a previous process left open; returns how many.
    int recover();

    std::optional<LiveState> state(std::int64_t run_id);

    // The service's encoding of force rows in live chunks: per row t_s (double), fx, fy, fz,
    // torque, power, chip (float), block (int32), little-endian.
    static std::vector<unsigned char> pack_rows(const std::vector<force_model::ForceSample>& rows);
    static std::vector<force_model::ForceSample> unpack_rows(std::span<const unsigned char> data);

private:
    struct Worker;
    void run_worker(std::shared_ptr<Worker> w);
    void close_stored(std::int64_t run_id, const std::string& reason);

    db::Store& store_;
    const ServerOptions& opt_;
    std::function<void()> on_alerts_;
    std::mutex mu_;
    std::map<std::int64_t, std::shared_ptr<Worker>> workers_;
};

}  // namespace cutload::server
