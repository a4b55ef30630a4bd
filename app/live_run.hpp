// Use case: predict while the dry run runs. Observations from a live source (an MTConnect SHDR
// adapter or agent, live/live.hpp) are mapped by the SHDR key map to readings, pushed through the
// ingest chain (motion_io/ingest_chain.hpp: the same repair a log file gets) and the grid goes to
// the force engine as it becomes final (force_model/streaming.hpp: stock carried, stock lag kept).
// Force rows and block summaries with their flags come out through callbacks as they are final.
// The run closes on program end (an execution state PROGRAM_COMPLETED, or READY / STOPPED after
// ACTIVE; a block reading M30 or M02), an explicit stop, or an idle time without data. A gap in the
// source (lost data, a reconnection) ends the motion session: nothing is interpolated across it.
// See docs/live.md, "Live runs".
#pragma once

#include "force_model/force_model.hpp"
#include "force_model/streaming.hpp"
#include "live/live.hpp"
#include "motion_io/ingest_chain.hpp"
#include "motion_io/shdr.hpp"

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace cutload::app {

struct LiveOptions {
    force_model::RunSpec spec;
    motion_io::ShdrKeyMap keys = motion_io::default_shdr_key_map();   // which keys feed which channel, their units
    // Values sent on change (an adapter, an agent: the default) or re-sent at the client's polling
    // rate (a controller export replayed, e.g. `cutload replay` of a CSV log).
    bool polled = false;
    std::size_t clock_batch_readings = 1024;   // polled only: less is less latency (docs/ingest.md)
    // How far back a reading may arrive out of time order and still be put in order; every
    // reading waits this long (an adapter or agent sends in order: the default keeps 0.1 s for
    // stragglers between channels, against 1 s for files).
    double reorder_horizon_s = 0.1;
    // The run closes (LiveEnd::Limit) once its motion grid holds this many samples: the grid is
    // kept for the stored run (about 100 B a sample), so a run left open cannot grow without
    // bound. 0: no limit (the service derives one from its job memory limit).
    std::size_t max_motion_samples = 0;
    double step_ms = 1.0;                       // motion grid
    std::chrono::milliseconds idle_timeout{std::chrono::minutes(5)};   // 0: never
    const force_model::Stock* base_stock = nullptr;
    force_model::Device device = force_model::Device::Cpu;
};

enum class LiveEnd { ProgramEnd, Stopped, Idle, Limit };
const char* to_string(LiveEnd e);   // "program_end", "stopped", "idle", "limit"

struct LiveGap {
    double t_s = 0;       // machine time of the last sample before it (run time, see LiveRun::origin_ns)
    double gap_s = 0;     // wall-clock time without data
    std::string message;
};

// What the front end sees while the run goes on. Called from the worker thread.
struct LiveCallbacks {
    // Final rows, in time order; `block_names` names their block indices (the list only grows).
    std::function<void(const std::vector<force_model::ForceSample>&, const std::vector<std::string>& block_names)> samples;
    std::function<void(const force_model::BlockSummary&)> block;                // a block ended
    std::function<void(const live::SourceEvent&)> event;                        // connection state, gaps, warnings
    // After `samples` returned (the front end stored them): the run time of the latest row and the
    // lag of the newest position reading whose force went out with them (its arrival to now).
    std::function<void(double machine_t_s, double lag_s)> stored;
};

struct LiveResult {
    LiveEnd end = LiveEnd::Stopped;
    std::string end_reason;                  // one line: what closed it
    force_model::Prediction prediction;      // blocks over the whole run, final stock, stats; no samples
    motion_io::MotionModel motion;           // the repaired motion grid, run time
    motion_io::IngestReport ingest;
    std::vector<LiveGap> gaps;
    std::vector<double> lags_s;              // per position reading: arrival to its force stored (LiveRun::lags_s)
    std::size_t observations = 0, force_rows = 0;
    std::int64_t origin_ns = 0;              // source stamp of run time 0 (the first observation)
};

// The run's state, fed from outside: the front end (or run_live) owns the source.
class LiveRun {
public:
    // Throws force_model::SpecError, motion_io::IngestError (a bad step).
    LiveRun(const LiveOptions& opt, const LiveCallbacks& cb);
    ~LiveRun();
    LiveRun(const LiveRun&) = delete;
    LiveRun& operator=(const LiveRun&) = delete;

    // One source batch, `arrived` when it came. Runs the engine over what became final and calls
    // the callbacks. Returns the end when the batch held the program's end.
    std::optional<LiveEnd> push(const live::Batch& batch, std::chrono::steady_clock::time_point arrived);
    // Closes the run: what is held comes out, the last block's summary.
    LiveResult finish(LiveEnd end, std::string reason);

    // Lag of each position reading: from its arrival to the return of the samples callback that
    // handed out its force (the front end stores them there). Seconds, in arrival order.
    const std::vector<double>& lags_s() const;
    std::int64_t origin_ns() const;      // 0 until the first observation
    double machine_t_s() const;          // run time of the latest force row handed out
    std::size_t observations() const;
    std::size_t motion_samples() const;   // grid samples walked so far

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

// The loop: reads `source` until the program ends, `stop` is set or the source is idle for
// opt.idle_timeout. Source trouble never throws (it arrives as events); a bad reading throws
// motion_io::IngestError.
LiveResult run_live(live::Source& source, const LiveOptions& opt, const LiveCallbacks& cb, const std::atomic<bool>& stop);

}  // namespace cutload::app
