// Internal to server: time series (forces, motion) stored as chunked blobs with a min/max
// envelope pyramid, and window queries that decimate wide windows to at most max_points buckets.
//
// Level 0 elements are raw rows: t_s (double) + K float channels. Level L > 0 elements cover
// kFanout^L raw rows: t0_s, t1_s (double) + K minima + K maxima (float). Blobs are host-endian
// (little-endian on every platform cutload targets).
#pragma once

#include "db/db.hpp"

#include <cstdint>
#include <string>
#include <vector>

namespace cutload::server {

enum class SeriesId : int { Forces = 0, Motion = 1 };

constexpr std::size_t kChunkElems = 4096;
// Small enough that the level a query reads holds at most kFanout x max_points elements.
constexpr std::size_t kFanout = 8;

const std::vector<std::string>& series_channels(SeriesId s);

// Row-major raw rows, values.size() == t_s.size() * channels.
struct SeriesData {
    std::vector<double> t_s;
    std::vector<float> values;
};

// Inside an open transaction.
void write_series(db::Connection& c, std::int64_t run_id, SeriesId s, const SeriesData& d);

struct Window {
    bool decimated = false;
    std::size_t channels = 0;
    std::vector<double> t_s;       // raw: sample times; decimated: first time in each bucket
    std::vector<double> t_end_s;   // decimated only: last time in each bucket
    std::vector<float> values;     // raw only: row-major
    std::vector<float> mins, maxs; // decimated only: row-major
    int level = 0;                 // pyramid level read
};

Window query_window(db::Connection& c, std::int64_t run_id, SeriesId s, double from_s, double to_s,
                    std::size_t max_points);

// First and last time stored, or false when the run has no rows in this series.
bool series_extent(db::Connection& c, std::int64_t run_id, SeriesId s, double* t0_s, double* t1_s);

}  // namespace cutload::server
