// PostgreSQL: the queue operations every job table shares. Several processes may claim from one
// queue: a claim locks the row it picks and skips rows another claim holds.
#include "postgres/store.hpp"

#include <fmt/format.h>

namespace cutload::db::postgres {

void notify_job_queued(Connection& c) {
    // Inside a transaction PostgreSQL delivers it at commit, and not at all on rollback.
    c.exec(fmt::format("NOTIFY {}", kJobsChannel));
}

std::optional<std::int64_t> Jobs::claim_oldest(const JobQueue& q, const std::string& now, const Lease& lease) {
    // FOR UPDATE SKIP LOCKED: two claims at once lock two different rows (the second skips the
    // first's) instead of both picking the oldest; the row is marked running in the same statement.
    auto r = c_.run(fmt::format("UPDATE {0} SET state = $1, started_at = $2, progress = 0, attempts = attempts + 1, "
                                "claim_token = $4, lease_until = $5 "
                                "WHERE id = (SELECT id FROM {0} WHERE state = $3 ORDER BY id LIMIT 1 FOR UPDATE SKIP LOCKED) "
                                "RETURNING id",
                                job_table(q)),
                    Params().add(to_text(JobState::Running)).add(now).add(to_text(JobState::Queued)).add(lease.token).add(lease.until));
    if (r.empty()) return std::nullopt;
    return r.i64(0, 0);
}

std::vector<std::int64_t> Jobs::renew_leases(const JobQueue& q, const std::string& token_prefix, const std::string& until) {
    // Held: read without waiting (a row this process is storing is locked by its own transaction,
    // and is held all the same). Renewed: the rows nobody has locked; a locked one needs no
    // renewal, since requeue_expired skips locked rows.
    auto held = c_.run(fmt::format("SELECT id FROM {} WHERE state = $1 AND left(claim_token, length($2)) = $2", job_table(q)),
                       Params().add(to_text(JobState::Running)).add(token_prefix));
    c_.run(fmt::format("UPDATE {0} SET lease_until = $1 WHERE id IN (SELECT id FROM {0} WHERE state = $2 AND "
                       "left(claim_token, length($3)) = $3 FOR UPDATE SKIP LOCKED)",
                       job_table(q)),
           Params().add(until).add(to_text(JobState::Running)).add(token_prefix));
    std::vector<std::int64_t> ids;
    for (int i = 0; i < held.rows(); ++i) ids.push_back(held.i64(i, 0));
    return ids;
}

namespace {

// Running jobs matching `which` (SQL over the job columns; $3 is `now`) back to queued, or failed
// at the attempt cap; both updates in one transaction: a job is either re-queued or failed.
Requeued requeue_where(Connection& c, const JobQueue& q, const char* which, int max_attempts, const std::string& error,
                       const std::string& now) {
    Requeued out;
    const auto body = [&] {
        // SKIP LOCKED: a row locked is being stored by the claim that holds it (holds()); waiting
        // for that commit would hold up this process's own renewals meanwhile.
        out.failed = static_cast<int>(
            c.run(fmt::format("UPDATE {0} SET state = $1, error = $2, finished_at = $3, claim_token = NULL "
                              "WHERE id IN (SELECT id FROM {0} WHERE state = $4 AND attempts >= $5 AND ({1}) "
                              "FOR UPDATE SKIP LOCKED)",
                              job_table(q), which),
                  Params().add(to_text(JobState::Failed)).add(error).add(now).add(to_text(JobState::Running)).add(max_attempts))
                .affected());
        out.requeued = static_cast<int>(
            c.run(fmt::format("UPDATE {0} SET state = $1, progress = 0, claim_token = NULL WHERE id IN (SELECT id FROM {0} "
                              "WHERE state = $2 AND ({1}) AND $3::text IS NOT NULL FOR UPDATE SKIP LOCKED)",
                              job_table(q), which),
                  Params().add(to_text(JobState::Queued)).add(to_text(JobState::Running)).add(now))
                .affected());
        if (out.requeued > 0) notify_job_queued(c);
    };
    if (c.in_transaction()) {
        body();
        return out;
    }
    c.exec("BEGIN");
    try {
        body();
        c.exec("COMMIT");
    } catch (...) {
        c.exec("ROLLBACK");
        throw;
    }
    return out;
}

}  // namespace

Requeued Jobs::requeue_interrupted(const JobQueue& q, int max_attempts, const std::string& error, const std::string& now) {
    // Every job running is taken as left by a process that is gone: only right while no other
    // process computes jobs of this database (a server with --workers and no `cutload worker`
    // beside it). With workers, requeue_expired tells a live claim from a dead one by its lease.
    return requeue_where(c_, q, "true", max_attempts, error, now);
}

Requeued Jobs::requeue_expired(const JobQueue& q, int max_attempts, const std::string& error, const std::string& now) {
    // Only leased claims: a live run is 'running' without one (its server follows the machine).
    // A claimant storing its results holds its row locked (holds()): that row is skipped.
    return requeue_where(c_, q, "lease_until IS NOT NULL AND lease_until < $3", max_attempts, error, now);
}

bool Jobs::holds(const JobQueue& q, std::int64_t id, const std::string& token) {
    // FOR UPDATE: inside the caller's transaction nobody re-queues or cancels the row until commit.
    return !c_.run(fmt::format("SELECT 1 FROM {} WHERE id = $1 AND state = $2 AND claim_token = $3 FOR UPDATE", job_table(q)),
                   Params().add(id).add(to_text(JobState::Running)).add(token))
                .empty();
}

void Jobs::finish(const JobQueue& q, std::int64_t id, JobState state, const std::optional<std::string>& error,
                  const std::string& now, const std::optional<std::string>& token) {
    const bool requeue = state == JobState::Queued;
    c_.run(fmt::format("UPDATE {} SET state = $1, error = $2, finished_at = $3, "
                       "progress = CASE WHEN $4 THEN 0 ELSE progress END, "
                       "attempts = CASE WHEN $4 THEN greatest(attempts - 1, 0) ELSE attempts END, claim_token = NULL "
                       "WHERE id = $5 AND state = $6 AND ($7::text IS NULL OR claim_token = $7)",
                       job_table(q)),
           Params()
               .add(to_text(state))
               .add(error)
               .add(requeue ? std::nullopt : std::optional<std::string>(now))
               .add(requeue)
               .add(id)
               .add(to_text(JobState::Running))
               .add(token));
    if (requeue) notify_job_queued(c_);
}

bool Jobs::cancel_running(const JobQueue& q, std::int64_t id, const std::string& now) {
    return c_.run(fmt::format("UPDATE {} SET state = $1, finished_at = $2, claim_token = NULL WHERE id = $3 AND state = $4 "
                              "AND claim_token IS NOT NULL",
                              job_table(q)),
                  Params().add(to_text(JobState::Cancelled)).add(now).add(id).add(to_text(JobState::Running)))
               .affected() > 0;
}

bool Jobs::cancel_queued(const JobQueue& q, std::int64_t id, const std::string& now) {
    return c_.run(fmt::format("UPDATE {} SET state = $1, finished_at = $2 WHERE id = $3 AND state = $4", job_table(q)),
                  Params().add(to_text(JobState::Cancelled)).add(now).add(id).add(to_text(JobState::Queued)))
               .affected() > 0;
}

void Jobs::set_progress(const JobQueue& q, std::int64_t id, double fraction) {
    c_.run(fmt::format("UPDATE {} SET progress = $1 WHERE id = $2 AND state = $3", job_table(q)),
           Params().add(fraction).add(id).add(to_text(JobState::Running)));
}

std::int64_t Jobs::count(const JobQueue& q, std::initializer_list<JobState> states) {
    std::vector<std::string> texts;
    for (const JobState s : states) texts.emplace_back(to_text(s));
    // One statement text for any set of states: an array parameter would need its own encoding,
    // so the states travel as one comma-joined text.
    std::string joined;
    for (const auto& t : texts) joined += (joined.empty() ? "" : ",") + t;
    return c_.run(fmt::format("SELECT count(*) FROM {} WHERE state = ANY (string_to_array($1, ','))", job_table(q)),
                  Params().add(joined))
        .i64(0, 0);
}

}  // namespace cutload::db::postgres
