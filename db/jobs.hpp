// Public interface of db: job states and job queues.
//
// A job is a row of a job table (runs, optimizations, ...): besides its own data it carries the
// job columns state, progress, error, attempts, started_at and finished_at. The JobRepository
// works on any job table by its queue name, so a new kind of job needs its table (a migration
// with those columns) and its own repository for its data, and gets claiming, finishing,
// cancelling, re-queueing and counting from here.
#pragma once

#include <cstdint>
#include <initializer_list>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace cutload::db {

// The life of a job: queued -> running -> done | failed | cancelled; running -> queued again when
// the server stops or dies mid-job.
enum class JobState { Queued, Running, Done, Failed, Cancelled };

// The one place where states meet their text (stored, and shown by the API).
std::string_view to_text(JobState s);
// Throws std::invalid_argument naming the text for anything that is not a state.
JobState job_state_from_text(std::string_view text);
std::optional<JobState> parse_job_state(std::string_view text);
// Every state, in the order above.
const std::vector<JobState>& job_states();

// A job table, named as in the schema ("runs", "optimizations"): a constant of the code, never
// text from a request.
struct JobQueue {
    std::string_view name;
    constexpr bool operator==(const JobQueue&) const = default;
};
inline constexpr JobQueue kRunQueue{"runs"};
inline constexpr JobQueue kOptimizationQueue{"optimizations"};

// What requeue_interrupted did.
struct Requeued {
    int requeued = 0;
    int failed = 0;   // at the attempt cap
};

// A claim is a lease: `token` names this one claim of the job (no two claims share one), and the
// job is held until `until` (ISO UTC text, as now_iso) unless the claimant renews it. A process
// that dies stops renewing; once its leases end, any process re-queues its jobs.
struct Lease {
    std::string token;
    std::string until;
};

// Queue operations shared by every job table. One server owns an SQLite store (a lock file guards
// it); on PostgreSQL several servers and workers claim from one queue with row locks and leases.
// These operations say what they guarantee, not how.
class JobRepository {
public:
    virtual ~JobRepository() = default;

    // Marks the oldest queued job running under `lease` (attempts + 1, progress 0, started_at) and
    // returns its id; nullopt when none is queued. Two claims never return the same job.
    virtual std::optional<std::int64_t> claim_oldest(const JobQueue& q, const std::string& now, const Lease& lease) = 0;

    // Moves the lease of every running job whose claim token starts with `token_prefix` to
    // `until`; returns the ids still held (a job cancelled or deleted elsewhere is missing).
    virtual std::vector<std::int64_t> renew_leases(const JobQueue& q, const std::string& token_prefix,
                                                   const std::string& until) = 0;

    // Jobs left running by a server that is gone go back to queued (progress 0), except those
    // already claimed max_attempts times: they fail with `error` (a job that kills the server
    // would otherwise loop for ever). Returns how many of each. Only for a store one process
    // owns: it takes every running job for a dead process's.
    virtual Requeued requeue_interrupted(const JobQueue& q, int max_attempts, const std::string& error,
                                         const std::string& now) = 0;

    // The same for claimed jobs whose lease ended before `now` (their claimant stopped renewing):
    // safe while other processes compute jobs of this queue. A job running without a claim (a
    // live run, which its server follows) is left alone.
    virtual Requeued requeue_expired(const JobQueue& q, int max_attempts, const std::string& error,
                                     const std::string& now) = 0;

    // Whether job `id` is running under the claim `token`. Inside a transaction it stays so until
    // the commit (the row is locked where the backend has row locks), so results stored in that
    // transaction are stored by the one claim that holds the job.
    virtual bool holds(const JobQueue& q, std::int64_t id, const std::string& token) = 0;

    // Ends a running job as failed, cancelled or queued (re-queued by a graceful stop: progress 0,
    // no finished_at, and its claim given back so attempts count only crashes);
    // error is kept for failed. A job no longer running (cancelled, deleted), or running under
    // another claim than `token` (when given), is left alone.
    virtual void finish(const JobQueue& q, std::int64_t id, JobState state, const std::optional<std::string>& error,
                        const std::string& now, const std::optional<std::string>& token) = 0;

    // Cancels a claimed running job in the store (its claimant, maybe another process, sees its
    // claim gone at its next lease renewal and stops); false when it is not running or has no
    // claim (a live run).
    virtual bool cancel_running(const JobQueue& q, std::int64_t id, const std::string& now) = 0;

    // Cancels a queued job; false when it is not queued (or does not exist).
    virtual bool cancel_queued(const JobQueue& q, std::int64_t id, const std::string& now) = 0;

    // Progress 0..1 of a running job; ignored once it is no longer running.
    virtual void set_progress(const JobQueue& q, std::int64_t id, double fraction) = 0;

    // Jobs in any of these states.
    virtual std::int64_t count(const JobQueue& q, std::initializer_list<JobState> states) = 0;
};

}  // namespace cutload::db
