// PostgreSQL: feed optimizations.
#include "postgres/store.hpp"

namespace cutload::db::postgres {
namespace {

constexpr const char* kSelect =
    "SELECT id, run_id, state, progress, error, params, result, created_at, started_at, finished_at FROM optimizations ";

OptimizationRecord optimization_row(const Result& r, int i) {
    OptimizationRecord o;
    o.id = r.i64(i, 0);
    o.run_id = r.i64(i, 1);
    o.state = job_state_from_text(r.text(i, 2));
    o.progress = r.real(i, 3);
    o.error = r.opt_text(i, 4);
    o.params_json = r.text(i, 5);
    o.result_json = r.opt_text(i, 6);
    o.created_at = r.text(i, 7);
    o.started_at = r.opt_text(i, 8);
    o.finished_at = r.opt_text(i, 9);
    return o;
}

}  // namespace

std::int64_t Optimizations::create(std::int64_t run_id, const std::string& params_json, const std::string& created_at) {
    // The identity column never hands an id out again after a delete.
    notify_job_queued(c_);
    return c_
        .run("INSERT INTO optimizations(run_id, state, params, created_at) VALUES ($1, $2, $3, $4) RETURNING id",
             Params().add(run_id).add(to_text(JobState::Queued)).add(params_json).add(created_at))
        .i64(0, 0);
}

std::optional<OptimizationRecord> Optimizations::get(std::int64_t id) {
    auto r = c_.run(std::string(kSelect) + "WHERE id = $1", Params().add(id));
    if (r.empty()) return std::nullopt;
    return optimization_row(r, 0);
}

std::optional<OptimizedProgram> Optimizations::program(std::int64_t id) {
    auto r = c_.run("SELECT state, run_id, program FROM optimizations WHERE id = $1", Params().add(id));
    if (r.empty()) return std::nullopt;
    return OptimizedProgram{job_state_from_text(r.text(0, 0)), r.i64(0, 1), r.opt_text(0, 2)};
}

std::vector<OptimizationRecord> Optimizations::of_run(std::int64_t run_id) {
    auto r = c_.run(std::string(kSelect) + "WHERE run_id = $1 ORDER BY id DESC", Params().add(run_id));
    std::vector<OptimizationRecord> out;
    for (int i = 0; i < r.rows(); ++i) out.push_back(optimization_row(r, i));
    return out;
}

std::vector<std::int64_t> Optimizations::ids_of_run(std::int64_t run_id, JobState state) {
    auto r = c_.run("SELECT id FROM optimizations WHERE run_id = $1 AND state = $2 ORDER BY id",
                    Params().add(run_id).add(to_text(state)));
    std::vector<std::int64_t> out;
    for (int i = 0; i < r.rows(); ++i) out.push_back(r.i64(i, 0));
    return out;
}

bool Optimizations::remove_unless_running(std::int64_t id) {
    return c_.run("DELETE FROM optimizations WHERE id = $1 AND state != $2", Params().add(id).add(to_text(JobState::Running)))
               .affected() > 0;
}

bool Optimizations::mark_done(std::int64_t id, const std::string& result_json, const std::string& program,
                              const std::string& finished_at) {
    return c_.run("UPDATE optimizations SET state = $1, progress = 1, result = $2, program = $3, finished_at = $4 "
                  "WHERE id = $5 AND state = $6",
                  Params().add(to_text(JobState::Done)).add(result_json).add(program).add(finished_at).add(id).add(
                      to_text(JobState::Running)))
               .affected() > 0;
}

}  // namespace cutload::db::postgres
