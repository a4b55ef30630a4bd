// A folder of one run's stock checkpoints (force_model::StockCheckpoint): the states a window of the
// run resumes its walk from instead of the log's start (docs/force_model.md, "Stock checkpoints").
// A whole run writes them (RunInput::checkpoints), a window reads them. Each is a file
// at-<sample>-<t_s>-<key>.stock.gz: the stock format (force_model::save_stock) gzipped at zlib's
// fastest level; <t_s> is the 16 hex digits of the time's bits (checked exactly against the motion)
// and <key> force_model::checkpoint_key's, so only a run of the same motion, spec and base stock
// resumes one. They are a cache: a missing, unreadable or foreign one only means a walk from the
// log's start.
#pragma once

#include "force_model/force_model.hpp"

#include <cstdint>
#include <filesystem>
#include <optional>

namespace cutload::app {

struct CheckpointFolder {
    std::filesystem::path dir;   // created when a whole run writes into it (its parent must exist)
    // Motion seconds between checkpoints at least (and at most kMaxCheckpoints a run).
    double every_s = 60;
};

// Each checkpoint of an hour's roughing on a 150 x 100 mm stock at 0.1 mm is about 30 MB gzipped and
// 1 s to write (bench_long): eight bound that to a few percent of the run.
inline constexpr int kMaxCheckpoints = 8;

// Writes one checkpoint (a temporary file renamed into place, so a reader never sees half of one).
// Throws std::runtime_error when it cannot.
void write_checkpoint(const std::filesystem::path& dir, std::uint64_t key, const force_model::StockCheckpoint& at,
                      const force_model::Stock& stock);

struct CheckpointFile {
    std::filesystem::path path;
    force_model::StockCheckpoint at;
};
// The latest checkpoint of this key at or before t_s; none when there is none.
std::optional<CheckpointFile> checkpoint_before(const std::filesystem::path& dir, std::uint64_t key, double t_s);
// Throws for a file that is not a whole checkpoint (std::runtime_error; std::bad_alloc for a
// header that asks for more than memory).
force_model::StockPtr read_checkpoint(const CheckpointFile& file);

// Temporary files a writer that died left behind.
void remove_unfinished_checkpoints(const std::filesystem::path& dir);
// The folder and all in it.
void remove_checkpoints(const std::filesystem::path& dir);

}  // namespace cutload::app
