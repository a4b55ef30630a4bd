// Public interface of db: runs and their results (per-block summaries, time series chunks, the
// final stock, the NC program comparison).
//
// JSON columns travel as JSON text: the store keeps what the service wrote and gives it back.
#pragma once

#include "db/jobs.hpp"

#include <cstdint>
#include <functional>
#include <optional>
#include <ostream>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace cutload::db {

struct RunRecord {
    std::int64_t id = 0;
    std::optional<std::string> name, program;
    std::optional<std::int64_t> machine_id, tool_id, material_id, base_run;
    JobState state = JobState::Queued;
    double progress = 0;
    std::optional<std::string> error;
    std::int64_t attempts = 0;
    std::string upload_dir;                    // relative to the data directory
    std::string inputs_json;                   // log, resolved spec, ingest report, NC program
    std::optional<std::string> summary_json;   // set with state done
    bool flagged = false;
    std::string created_at;
    std::optional<std::string> started_at, finished_at;
};

// What a query of results needs first: whether the run is done, since when (a finished run's
// results never change, so finished_at versions them) and where its files are.
struct RunStatus {
    JobState state = JobState::Queued;
    std::optional<std::string> finished_at;
    std::string upload_dir;
};

struct NewRun {
    std::optional<std::string> name, program;
    std::optional<std::int64_t> machine_id, tool_id, material_id, base_run;
    std::string inputs_json;
    std::string created_at;
};

// Newest first; each field narrows the list when set.
struct RunFilter {
    std::optional<std::int64_t> before_id;   // the page cursor: ids below it
    std::optional<std::int64_t> machine_id;
    std::optional<std::string> program;
    std::optional<JobState> state;
    std::optional<bool> flagged;
    std::optional<std::string> created_since, created_until;   // inclusive, ISO 8601 text
    std::int64_t limit = 50;
};

struct BlockRow {
    std::int64_t idx = 0;
    std::string body_json;
};

// One chunk of a stored time series: `n` elements of level `level` (0: raw rows) covering
// t0_s..t1_s. The bytes are the series' own encoding; the store keeps them as they are.
struct SeriesChunkInfo {
    int series = 0;
    int level = 0;
    std::int64_t chunk = 0;
    double t0_s = 0, t1_s = 0;
    std::int64_t n = 0;
};

class RunRepository {
public:
    virtual ~RunRepository() = default;

    // A queued run with an empty upload_dir (set_upload_dir names it once the id is known).
    virtual std::int64_t create(const NewRun& run) = 0;
    virtual void set_upload_dir(std::int64_t id, const std::string& upload_dir) = 0;
    virtual std::optional<RunRecord> get(std::int64_t id) = 0;
    virtual std::optional<RunStatus> status(std::int64_t id) = 0;
    virtual std::vector<RunRecord> list(const RunFilter& f) = 0;
    // Removes the run and everything stored for it; false when there was no such run.
    virtual bool remove(std::int64_t id) = 0;
    // Whether a run owns this upload directory (orphans are removed at start-up).
    virtual bool upload_dir_in_use(const std::string& upload_dir) = 0;

    // Results, written in the transaction that marks the run done.
    virtual void add_block(std::int64_t run_id, std::int64_t idx, const std::string& body_json, bool flagged) = 0;
    virtual void add_series_chunk(std::int64_t run_id, const SeriesChunkInfo& info, std::span<const unsigned char> data) = 0;
    // The final stock: `write` puts exactly `bytes` bytes (force_model::save_stock's) into the stream
    // it is given. SQLite takes them into the row as they come, so the stock is never held whole
    // twice; PostgreSQL gathers them first.
    virtual void set_final_stock(std::int64_t run_id, std::uint64_t bytes,
                                 const std::function<void(std::ostream&)>& write) = 0;
    virtual void set_program_body(std::int64_t run_id, const std::string& body_json) = 0;
    virtual void mark_done(std::int64_t run_id, const std::string& summary_json, const std::string& block_names_json,
                           bool flagged, const std::string& finished_at) = 0;

    // Blocks from idx `from_idx` on, in order, at most `limit`; only (un)flagged ones when set.
    virtual std::vector<BlockRow> blocks(std::int64_t run_id, std::int64_t from_idx, std::optional<bool> flagged,
                                         std::int64_t limit) = 0;
    // Every chunk of one series, by level then chunk; no data is read.
    virtual std::vector<SeriesChunkInfo> series_index(std::int64_t run_id, int series) = 0;
    // Hands one chunk's element count and bytes to `use` (valid during the call only); false when
    // there is no such chunk.
    virtual bool read_series_chunk(std::int64_t run_id, int series, int level, std::int64_t chunk,
                                   const std::function<void(std::int64_t n, std::span<const unsigned char> data)>& use) = 0;
    virtual bool has_final_stock(std::int64_t run_id) = 0;
    // Hands the final stock's bytes to `use` (valid during the call only: no copy of a stock that
    // may be tens of megabytes); false when the run has none.
    virtual bool read_final_stock(std::int64_t run_id, const std::function<void(std::span<const unsigned char> bytes)>& use) = 0;
    virtual std::optional<std::string> program_body(std::int64_t run_id) = 0;
    // The JSON array naming the block indices of the series; nullopt before the run is done.
    virtual std::optional<std::string> block_names(std::int64_t run_id) = 0;
};

}  // namespace cutload::db
