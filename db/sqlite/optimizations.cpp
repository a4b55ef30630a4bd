// SQLite: feed optimizations.
#include "sqlite/store.hpp"

namespace cutload::db::sqlite {
namespace {

constexpr const char* kSelect =
    "SELECT id, run_id, state, progress, error, params, result, created_at, started_at, finished_at FROM optimizations ";

OptimizationRecord optimization_row(const Stmt& st) {
    OptimizationRecord o;
    o.id = st.i64(0);
    o.run_id = st.i64(1);
    o.state = job_state_from_text(st.text(2));
    o.progress = st.real(3);
    o.error = st.opt_text(4);
    o.params_json = st.text(5);
    o.result_json = st.opt_text(6);
    o.created_at = st.text(7);
    o.started_at = st.opt_text(8);
    o.finished_at = st.opt_text(9);
    return o;
}

}  // namespace

std::int64_t Optimizations::create(std::int64_t run_id, const std::string& params_json, const std::string& created_at) {
    // The table's AUTOINCREMENT keeps ids from being handed out again after a delete.
    c_.prepare("INSERT INTO optimizations(run_id, state, params, created_at) VALUES (?, ?, ?, ?)")
        .bind(1, run_id)
        .bind(2, to_text(JobState::Queued))
        .bind(3, params_json)
        .bind(4, created_at)
        .run();
    return c_.last_insert_id();
}

std::optional<OptimizationRecord> Optimizations::get(std::int64_t id) {
    auto st = c_.prepare(std::string(kSelect) + "WHERE id = ?");
    st.bind(1, id);
    if (!st.step()) return std::nullopt;
    return optimization_row(st);
}

std::optional<OptimizedProgram> Optimizations::program(std::int64_t id) {
    auto st = c_.prepare("SELECT state, run_id, program FROM optimizations WHERE id = ?");
    st.bind(1, id);
    if (!st.step()) return std::nullopt;
    return OptimizedProgram{job_state_from_text(st.text(0)), st.i64(1), st.opt_text(2)};
}

std::vector<OptimizationRecord> Optimizations::of_run(std::int64_t run_id) {
    auto st = c_.prepare(std::string(kSelect) + "WHERE run_id = ? ORDER BY id DESC");
    st.bind(1, run_id);
    std::vector<OptimizationRecord> out;
    while (st.step()) out.push_back(optimization_row(st));
    return out;
}

std::vector<std::int64_t> Optimizations::ids_of_run(std::int64_t run_id, JobState state) {
    auto st = c_.prepare("SELECT id FROM optimizations WHERE run_id = ? AND state = ? ORDER BY id");
    st.bind(1, run_id).bind(2, to_text(state));
    std::vector<std::int64_t> out;
    while (st.step()) out.push_back(st.i64(0));
    return out;
}

bool Optimizations::remove_unless_running(std::int64_t id) {
    c_.prepare("DELETE FROM optimizations WHERE id = ? AND state != ?").bind(1, id).bind(2, to_text(JobState::Running)).run();
    return c_.changes() > 0;
}

bool Optimizations::mark_done(std::int64_t id, const std::string& result_json, const std::string& program,
                              const std::string& finished_at) {
    c_.prepare(
          "UPDATE optimizations SET state = ?1, progress = 1, result = ?2, program = ?3, finished_at = ?4 "
          "WHERE id = ?5 AND state = ?6")
        .bind(1, to_text(JobState::Done))
        .bind(2, result_json)
        .bind(3, program)
        .bind(4, finished_at)
        .bind(5, id)
        .bind(6, to_text(JobState::Running))
        .run();
    return c_.changes() > 0;
}

}  // namespace cutload::db::sqlite
