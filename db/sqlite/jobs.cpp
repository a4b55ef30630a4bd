// SQLite: the queue operations every job table shares.
#include "sqlite/store.hpp"

#include <fmt/format.h>

namespace cutload::db::sqlite {

std::optional<std::int64_t> Jobs::claim_oldest(const JobQueue& q, const std::string& now) {
    // One statement: the row is marked running by the same write that picks it, so two workers
    // (on two connections) never claim one job.
    auto st = c_.prepare(fmt::format(
        "UPDATE {0} SET state = ?1, started_at = ?2, progress = 0, attempts = attempts + 1 "
        "WHERE id = (SELECT id FROM {0} WHERE state = ?3 ORDER BY id LIMIT 1) RETURNING id",
        job_table(q)));
    st.bind(1, to_text(JobState::Running)).bind(2, now).bind(3, to_text(JobState::Queued));
    if (!st.step()) return std::nullopt;
    const std::int64_t id = st.i64(0);
    st.run();
    return id;
}

Requeued Jobs::requeue_interrupted(const JobQueue& q, int max_attempts, const std::string& error, const std::string& now) {
    // Only one server owns an SQLite database (the lock file beside it), so a job still running
    // when that server starts was left by a process that died. Both updates in one transaction:
    // a job is either re-queued or failed.
    Savepoint tx(c_, "requeue_interrupted");
    Requeued r;
    c_.prepare(fmt::format("UPDATE {} SET state = ?1, error = ?2, finished_at = ?3 WHERE state = ?4 AND attempts >= ?5",
                           job_table(q)))
        .bind(1, to_text(JobState::Failed))
        .bind(2, error)
        .bind(3, now)
        .bind(4, to_text(JobState::Running))
        .bind(5, max_attempts)
        .run();
    r.failed = c_.changes();
    c_.prepare(fmt::format("UPDATE {} SET state = ?1, progress = 0 WHERE state = ?2", job_table(q)))
        .bind(1, to_text(JobState::Queued))
        .bind(2, to_text(JobState::Running))
        .run();
    r.requeued = c_.changes();
    tx.release();
    return r;
}

void Jobs::finish(const JobQueue& q, std::int64_t id, JobState state, const std::optional<std::string>& error,
                  const std::string& now) {
    const bool requeue = state == JobState::Queued;
    auto st = c_.prepare(fmt::format(
        "UPDATE {} SET state = ?1, error = ?2, finished_at = ?3, progress = CASE WHEN ?4 THEN 0 ELSE progress END, "
        "attempts = CASE WHEN ?4 THEN max(attempts - 1, 0) ELSE attempts END "
        "WHERE id = ?5 AND state = ?6",
        job_table(q)));
    st.bind(1, to_text(state)).bind(2, error);
    if (requeue)
        st.bind_null(3);
    else
        st.bind(3, now);
    st.bind(4, requeue).bind(5, id).bind(6, to_text(JobState::Running)).run();
}

bool Jobs::cancel_queued(const JobQueue& q, std::int64_t id, const std::string& now) {
    c_.prepare(fmt::format("UPDATE {} SET state = ?1, finished_at = ?2 WHERE id = ?3 AND state = ?4", job_table(q)))
        .bind(1, to_text(JobState::Cancelled))
        .bind(2, now)
        .bind(3, id)
        .bind(4, to_text(JobState::Queued))
        .run();
    return c_.changes() > 0;
}

void Jobs::set_progress(const JobQueue& q, std::int64_t id, double fraction) {
    c_.prepare(fmt::format("UPDATE {} SET progress = ?1 WHERE id = ?2 AND state = ?3", job_table(q)))
        .bind(1, fraction)
        .bind(2, id)
        .bind(3, to_text(JobState::Running))
        .run();
}

std::int64_t Jobs::count(const JobQueue& q, std::initializer_list<JobState> states) {
    std::string marks;
    for (std::size_t i = 1; i <= states.size(); ++i) marks += fmt::format("{}?{}", i > 1 ? ", " : "", i);
    auto st = c_.prepare(fmt::format("SELECT count(*) FROM {} WHERE state IN ({})", job_table(q), marks));
    int i = 0;
    for (const JobState s : states) st.bind(++i, to_text(s));
    st.step();
    return st.i64(0);
}

}  // namespace cutload::db::sqlite
