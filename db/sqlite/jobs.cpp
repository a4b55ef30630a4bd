// SQLite: the queue operations every job table shares.
#include "sqlite/store.hpp"

#include <fmt/format.h>

namespace cutload::db::sqlite {

std::optional<std::int64_t> Jobs::claim_oldest(const JobQueue& q, const std::string& now, const Lease& lease) {
    // One statement: the row is marked running by the same write that picks it, so two workers
    // (on two connections) never claim one job.
    auto st = c_.prepare(fmt::format(
        "UPDATE {0} SET state = ?1, started_at = ?2, progress = 0, attempts = attempts + 1, claim_token = ?4, "
        "lease_until = ?5 WHERE id = (SELECT id FROM {0} WHERE state = ?3 ORDER BY id LIMIT 1) RETURNING id",
        job_table(q)));
    st.bind(1, to_text(JobState::Running)).bind(2, now).bind(3, to_text(JobState::Queued)).bind(4, lease.token).bind(5, lease.until);
    if (!st.step()) return std::nullopt;
    const std::int64_t id = st.i64(0);
    st.run();
    return id;
}

std::vector<std::int64_t> Jobs::renew_leases(const JobQueue& q, const std::string& token_prefix, const std::string& until) {
    auto st = c_.prepare(fmt::format("UPDATE {} SET lease_until = ?1 WHERE state = ?2 AND substr(claim_token, 1, length(?3)) = ?3 "
                                     "RETURNING id",
                                     job_table(q)));
    st.bind(1, until).bind(2, to_text(JobState::Running)).bind(3, token_prefix);
    std::vector<std::int64_t> ids;
    while (st.step()) ids.push_back(st.i64(0));
    return ids;
}

namespace {

// Running jobs matching `which` (SQL over the job columns; ?4 is `now`) back to queued, or
// failed at the attempt cap; both updates in one transaction: a job is either re-queued or failed.
Requeued requeue_where(Connection& c, const JobQueue& q, const char* which, int max_attempts, const std::string& error,
                       const std::string& now) {
    Savepoint tx(c, "requeue");
    Requeued r;
    c.prepare(fmt::format("UPDATE {} SET state = ?1, error = ?2, finished_at = ?4, claim_token = NULL "
                          "WHERE state = ?3 AND attempts >= ?5 AND ({})",
                          job_table(q), which))
        .bind(1, to_text(JobState::Failed))
        .bind(2, error)
        .bind(3, to_text(JobState::Running))
        .bind(4, now)
        .bind(5, max_attempts)
        .run();
    r.failed = c.changes();
    c.prepare(fmt::format("UPDATE {} SET state = ?1, progress = 0, claim_token = NULL WHERE state = ?3 AND ({}) "
                          "AND ?4 IS NOT NULL",
                          job_table(q), which))
        .bind(1, to_text(JobState::Queued))
        .bind(3, to_text(JobState::Running))
        .bind(4, now)
        .run();
    r.requeued = c.changes();
    tx.release();
    return r;
}

}  // namespace

Requeued Jobs::requeue_interrupted(const JobQueue& q, int max_attempts, const std::string& error, const std::string& now) {
    // Only one server owns an SQLite database (the lock file beside it), so a job still running
    // when that server starts was left by a process that died.
    return requeue_where(c_, q, "1", max_attempts, error, now);
}

Requeued Jobs::requeue_expired(const JobQueue& q, int max_attempts, const std::string& error, const std::string& now) {
    // Only leased claims: a live run is 'running' without one (its server follows the machine).
    return requeue_where(c_, q, "lease_until IS NOT NULL AND lease_until < ?4", max_attempts, error, now);
}

bool Jobs::holds(const JobQueue& q, std::int64_t id, const std::string& token) {
    // A write transaction holds the database's write lock, so the answer stays true until commit.
    auto st = c_.prepare(fmt::format("SELECT 1 FROM {} WHERE id = ?1 AND state = ?2 AND claim_token = ?3", job_table(q)));
    st.bind(1, id).bind(2, to_text(JobState::Running)).bind(3, token);
    return st.step();
}

void Jobs::finish(const JobQueue& q, std::int64_t id, JobState state, const std::optional<std::string>& error,
                  const std::string& now, const std::optional<std::string>& token) {
    const bool requeue = state == JobState::Queued;
    auto st = c_.prepare(fmt::format(
        "UPDATE {} SET state = ?1, error = ?2, finished_at = ?3, progress = CASE WHEN ?4 THEN 0 ELSE progress END, "
        "attempts = CASE WHEN ?4 THEN max(attempts - 1, 0) ELSE attempts END, claim_token = NULL "
        "WHERE id = ?5 AND state = ?6 AND (?7 IS NULL OR claim_token = ?7)",
        job_table(q)));
    st.bind(1, to_text(state)).bind(2, error);
    if (requeue)
        st.bind_null(3);
    else
        st.bind(3, now);
    st.bind(4, requeue).bind(5, id).bind(6, to_text(JobState::Running)).bind(7, token).run();
}

bool Jobs::cancel_running(const JobQueue& q, std::int64_t id, const std::string& now) {
    c_.prepare(fmt::format("UPDATE {} SET state = ?1, finished_at = ?2, claim_token = NULL WHERE id = ?3 AND state = ?4 "
                           "AND claim_token IS NOT NULL",
                           job_table(q)))
        .bind(1, to_text(JobState::Cancelled))
        .bind(2, now)
        .bind(3, id)
        .bind(4, to_text(JobState::Running))
        .run();
    return c_.changes() > 0;
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
