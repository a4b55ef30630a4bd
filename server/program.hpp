// Internal to server: NC programs of runs. The upload's nc_options, what a run job stores of its
// commanded prediction, and the optimization jobs that recommend feeds.
#pragma once

#include "app/optimize.hpp"
#include "app/predict_run.hpp"
#include "common.hpp"

#include <atomic>
#include <filesystem>
#include <functional>

namespace cutload::server {

// nc_options (JSON object) as program settings; ApiError 400 `bad_request` naming the key.
app::ProgramSettings program_settings(const json& options);

// The NC program of a run's inputs (`nc_program`: the stored file, its name as uploaded, options).
app::ProgramSource program_source(const json& nc_program, const std::filesystem::path& upload_dir);

struct ProgramResult {
    const app::ProgramRun& run;
    const app::ProgramPrediction& prediction;
    std::string filename;
};

// What GET /runs/{id}/program answers (stored in run_program.body); `commanded_summary` is the
// commanded prediction's summary in the form of a run's summary.
json program_body(const ProgramResult& r, const json& commanded_summary);

// The comparison rows of a program body as CSV (the columns of `cutload predict --compare`).
std::string comparison_csv(const json& blocks);

// Feed optimization request body as stored params; ApiError 400 naming the key.
json optimization_params(const json& body);

// Computes optimization `id` (claimed under `claim`, state 'running') and stores its result; false
// when the claim no longer holds it (deleted, cancelled or re-queued meanwhile: nothing stored).
// Throws force_model::Cancelled when `cancel` is set; other exceptions are the job's failure.
bool run_optimization(db::Store& store, const std::filesystem::path& data_dir, bool use_opencl, std::int64_t id,
                      const std::string& claim, const std::atomic<bool>& cancel,
                      const std::function<void(double)>& progress);

}  // namespace cutload::server
