// Public interface of db: feed optimizations of runs (jobs in the optimizations queue).
#pragma once

#include "db/jobs.hpp"

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace cutload::db {

struct OptimizationRecord {
    std::int64_t id = 0;
    std::int64_t run_id = 0;
    JobState state = JobState::Queued;
    double progress = 0;
    std::optional<std::string> error;
    std::string params_json;
    std::optional<std::string> result_json;   // set with state done
    std::string created_at;
    std::optional<std::string> started_at, finished_at;
};

// The optimized NC program (set with state done) and what it belongs to.
struct OptimizedProgram {
    JobState state = JobState::Queued;
    std::int64_t run_id = 0;
    std::optional<std::string> program;
};

class OptimizationRepository {
public:
    virtual ~OptimizationRepository() = default;

    // A queued optimization. Ids are never given out twice, even after a delete: a job that
    // outlives its row must never write into another's.
    virtual std::int64_t create(std::int64_t run_id, const std::string& params_json, const std::string& created_at) = 0;
    virtual std::optional<OptimizationRecord> get(std::int64_t id) = 0;
    virtual std::optional<OptimizedProgram> program(std::int64_t id) = 0;
    // Newest first.
    virtual std::vector<OptimizationRecord> of_run(std::int64_t run_id) = 0;
    virtual std::vector<std::int64_t> ids_of_run(std::int64_t run_id, JobState state) = 0;
    // Removes it unless running; false when nothing was removed.
    virtual bool remove_unless_running(std::int64_t id) = 0;
    // Stores the result of a running optimization and marks it done; false when it is no longer
    // running (cancelled or deleted meanwhile), and then nothing is stored.
    virtual bool mark_done(std::int64_t id, const std::string& result_json, const std::string& program,
                           const std::string& finished_at) = 0;
};

}  // namespace cutload::db
