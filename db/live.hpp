// Public interface of db: live runs (docs/live.md, "Live runs in the service"). A live run is a
// run row in state 'running' from its start, with a live record beside it holding what the run
// page follows while the machine runs: the connection state, the lag, force rows in chunks and
// block summaries as they complete, each with a sequence number for cursors. When the run closes
// its results are written as any run's (RunRepository) and the live record is closed in the same
// transaction; its rows go.
#pragma once

#include "db/runs.hpp"

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace cutload::db {

struct LiveRecord {
    std::int64_t run_id = 0;
    std::string source_json;        // how it was started: source, key map, options
    bool open = true;               // false once closed
    std::string connection;         // connecting, connected, disconnected, closed
    double lag_ms = 0;              // latest: a sample's arrival to its force stored
    double machine_t_s = 0;         // run time of the latest force row stored
    std::int64_t rows = 0;          // force rows stored
    std::string gaps_json = "[]";   // [{t_s, gap_s, message}]
    std::string block_names_json = "[]";   // names of the block indices in the chunks' rows
    std::int64_t alerts = 0;        // alerts raised so far
    std::optional<std::string> end_reason;
    std::string updated_at;
};

struct LiveStatusUpdate {
    std::string connection;
    double lag_ms = 0, machine_t_s = 0;
    std::int64_t rows = 0;
    std::string gaps_json = "[]";
    std::string block_names_json = "[]";
    std::int64_t alerts = 0;
    std::string updated_at;
};

// One stored piece of the force trace: `n` rows (the service's own encoding) from t0_s to t1_s.
struct LiveChunk {
    std::int64_t seq = 0;
    double t0_s = 0, t1_s = 0;
    std::int64_t n = 0;
    std::vector<unsigned char> data;
};

class LiveRunRepository {
public:
    virtual ~LiveRunRepository() = default;

    // The run (state 'running', started now) and its open live record, in one step.
    virtual std::int64_t create(const NewRun& run, const std::string& source_json) = 0;
    virtual std::optional<LiveRecord> get(std::int64_t run_id) = 0;
    // Runs whose live record is open (after a restart: those the service left).
    virtual std::vector<std::int64_t> open_runs() = 0;
    virtual void update_status(std::int64_t run_id, const LiveStatusUpdate& u) = 0;
    // Appends a chunk; returns its sequence number (increasing per run, from 1).
    virtual std::int64_t add_chunk(std::int64_t run_id, double t0_s, double t1_s, std::int64_t n,
                                   std::span<const unsigned char> data) = 0;
    // Chunks with seq > after_seq, in order, at most `limit`.
    virtual std::vector<LiveChunk> chunks(std::int64_t run_id, std::int64_t after_seq, std::int64_t limit) = 0;
    // A completed block's summary (JSON, as the blocks API shows it), idx from 0 in order.
    virtual void add_block(std::int64_t run_id, std::int64_t idx, const std::string& body_json, bool flagged) = 0;
    virtual std::vector<BlockRow> blocks(std::int64_t run_id, std::int64_t from_idx) = 0;
    // Closes the record: its chunks and blocks are removed (the run's results hold them now).
    virtual void close(std::int64_t run_id, const std::string& end_reason, const std::string& now) = 0;
};

}  // namespace cutload::db
