// Internal to server: a stored run's stock checkpoints (force_model::StockCheckpoint), the states
// a recomputed window (/forces?resolution=full) resumes its walk from instead of the log's start.
// They are files beside the run's uploads, checkpoints/at-<sample>-<t_s>.stock.gz: the stock
// format (force_model::save_stock) gzipped at zlib's fastest level, <t_s> the 16 hex digits of the
// double's bits (the time is checked exactly against the motion on resume). They are a cache: a
// missing or unreadable one only means a walk from further back (docs/api.md, "Recomputed windows").
#pragma once

#include "app/predict_run.hpp"   // force_model::StockCheckpoint, Stock

#include <cstdint>
#include <filesystem>
#include <optional>

namespace cutload::server {

// Writes one checkpoint under run_dir (a temporary file renamed into place, so a reader never sees
// half of one). Throws std::runtime_error when it cannot, also when run_dir is gone (the run was
// deleted meanwhile).
void write_checkpoint(const std::filesystem::path& run_dir, const force_model::StockCheckpoint& at,
                      const force_model::Stock& stock);

struct CheckpointFile {
    std::filesystem::path path;
    force_model::StockCheckpoint at;
};
// The latest checkpoint of the run at or before t_s; none when there is none.
std::optional<CheckpointFile> checkpoint_before(const std::filesystem::path& run_dir, double t_s);
// Throws std::runtime_error for a file that is not a whole checkpoint.
force_model::StockPtr read_checkpoint(const CheckpointFile& file);
// Temporary files a claimant that died left behind.
void remove_unfinished_checkpoints(const std::filesystem::path& run_dir);
// All of them (a run that failed or was cancelled is never recomputed).
void remove_checkpoints(const std::filesystem::path& run_dir);

}  // namespace cutload::server
