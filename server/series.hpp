// Internal to server: time series (forces, motion) stored as chunked blobs with a min/max
// envelope pyramid, window queries that decimate wide windows to at most max_points buckets, and
// the in-memory cache of decoded chunks those queries read from.
//
// Level 0 elements are raw rows: t_s (double) + K float channels. Level L > 0 elements cover
// kFanout^L raw rows: t0_s, t1_s (double) + K minima + K maxima (float). Blobs are host-endian
// (little-endian on every platform cutload targets).
#pragma once

#include "db/runs.hpp"
#include "db/store.hpp"

#include <cstdint>
#include <functional>
#include <list>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <unordered_map>
#include <vector>

namespace cutload::server {

// CommandedForces: forces predicted from a run's NC program (same channels as Forces). ToolAxis:
// the axis of a tool that turned while it cut (app::RunResult::motion_tool_axis), one row per
// motion sample at the motion's times, so its chunks and envelopes line up with Motion's and
// /motion answers it as three more channels; other runs store none.
enum class SeriesId : int { Forces = 0, Motion = 1, CommandedForces = 2, ToolAxis = 3 };

constexpr std::size_t kChunkElems = 4096;
// Small enough that the level a query reads holds at most kFanout x max_points elements.
constexpr std::size_t kFanout = 8;

const std::vector<std::string>& series_channels(SeriesId s);

// Row-major raw rows, values.size() == t_s.size() * channels.
struct SeriesData {
    std::vector<double> t_s;
    std::vector<float> values;
};

// Where a builder's chunks go (the store, inside an open transaction, or a spool file).
using ChunkSink = std::function<void(const db::SeriesChunkInfo& info, std::span<const unsigned char> blob)>;

// A series' chunks and envelope pyramid built as its rows come, holding one chunk and one group
// per level: the memory a run's series needs does not grow with its length. The chunks are those
// one pass over all the rows gives (write_series). Levels below `first_level` are reduced but not
// stored: a long run keeps envelopes (level 2: 64 rows, about a tooth pass at 2 deg steps and two
// flutes) rather than every row (docs/api.md, "Long runs").
class SeriesBuilder {
public:
    SeriesBuilder(SeriesId s, ChunkSink sink, int first_level = 0);
    ~SeriesBuilder();
    SeriesBuilder(const SeriesBuilder&) = delete;
    SeriesBuilder& operator=(const SeriesBuilder&) = delete;
    // One raw row: its time and series_channels(s).size() values.
    void add(double t_s, const float* values);
    // The last chunks of every level; nothing is added after it.
    void finish();
    std::size_t rows() const;

private:
    struct Level;
    void add_element(std::size_t level, double t0, double t1, const float* lo, const float* hi);
    void flush_group(std::size_t level);
    void flush_chunk(std::size_t level);
    SeriesId series_;
    std::size_t k_;
    int first_level_;
    ChunkSink sink_;
    std::vector<Level> levels_;
};

// A sink that stores each chunk as a row of the run's series (inside an open transaction).
ChunkSink store_chunks(db::RunRepository& runs, std::int64_t run_id);

// Inside an open transaction.
void write_series(db::RunRepository& runs, std::int64_t run_id, SeriesId s, const SeriesData& d);

// A finished run's results never change, but a deleted run's id can be given to the next upload:
// `version` (the run's finished_at) keeps the two apart in the cache.
struct RunRef {
    std::int64_t id = 0;
    std::string version;
};

// Decoded pieces of finished runs (chunk index, chunks, block names) shared by every request and
// bounded in bytes, least recently used out first. Thread-safe.
class SeriesCache {
public:
    explicit SeriesCache(std::size_t limit_bytes) : limit_bytes_(limit_bytes) {}

    struct Stats {
        std::size_t bytes = 0, limit_bytes = 0, entries = 0;
        std::uint64_t hits = 0, misses = 0, evictions = 0;
    };
    Stats stats() const;
    // Drops every entry of the run (on delete).
    void forget_run(std::int64_t run_id);

    // Answer: a whole-run series answer, the one every plot asks first; its level holds
    // max_points and its chunk the bit mask of channels asked, shifted left twice, | 2 for CSV,
    // | 1 when gzipped.
    enum class Kind : int { Index, Chunk, BlockNames, Answer };
    struct Key {
        std::int64_t run_id;
        std::string version;
        Kind kind;
        int series, level;
        std::int64_t chunk;
        bool operator==(const Key&) const = default;
    };

    // The cached value, or load()'s (cached when it fits). load returns the value and its size.
    // Concurrent misses of one key may both load; the values are equal, either is kept.
    template <class T>
    std::shared_ptr<const T> get(const Key& key, const std::function<std::pair<std::shared_ptr<const T>, std::size_t>()>& load) {
        if (auto hit = find(key)) return std::static_pointer_cast<const T>(hit);
        auto [value, bytes] = load();
        put(key, value, bytes);
        return value;
    }

private:
    struct KeyHash {
        std::size_t operator()(const Key& k) const;
    };
    struct Entry {
        Key key;
        std::shared_ptr<const void> value;
        std::size_t bytes;
    };
    std::shared_ptr<const void> find(const Key& key);
    void put(const Key& key, std::shared_ptr<const void> value, std::size_t bytes);

    const std::size_t limit_bytes_;
    mutable std::mutex mu_;
    std::list<Entry> lru_;   // most recently used first
    std::unordered_map<Key, std::list<Entry>::iterator, KeyHash> where_;
    std::size_t bytes_ = 0;
    std::uint64_t hits_ = 0, misses_ = 0, evictions_ = 0;
};

struct Window {
    bool decimated = false;
    int level = 0;                 // pyramid level read
    std::vector<double> t_s;       // raw: sample times; decimated: first time in each bucket
    std::vector<double> t_end_s;   // decimated only: last time in each bucket
    // Per channel (series_channels order), empty for channels not asked for. Raw: lo holds the
    // values and hi stays empty; decimated: minimum and maximum of each bucket.
    std::vector<std::vector<float>> lo, hi;
};

// First and last time stored, or false when the run has no rows in this series.
bool series_extent(db::Session& c, SeriesCache& cache, const RunRef& run, SeriesId s, double* t0_s, double* t1_s);

// The window of rows computed on demand (not stored: /forces?resolution=full), as query_window
// answers level 0: raw when at most max_points rows lie in [from_s, to_s], else min/max per equal
// bucket. d.values holds channels.size() values a row.
Window window_from_rows(const SeriesData& d, double from_s, double to_s, std::size_t max_points,
                        const std::vector<bool>& channels);

// channels[j]: whether channel j is wanted in the answer.
Window query_window(db::Session& c, SeriesCache& cache, const RunRef& run, SeriesId s, double from_s, double to_s,
                    std::size_t max_points, const std::vector<bool>& channels);

}  // namespace cutload::server
