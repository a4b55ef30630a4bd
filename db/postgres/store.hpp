// Private to db: the PostgreSQL backend (libpq). One file per repository (runs.cpp, jobs.cpp, ...),
// each a class over one Connection; a Session holds a connection and one of each. The same
// repository semantics as db/sqlite/, with what differs said where it differs.
#pragma once

#include "db/alerts.hpp"
#include "db/api_keys.hpp"
#include "db/jobs.hpp"
#include "db/library.hpp"
#include "db/live.hpp"
#include "db/optimizations.hpp"
#include "db/runs.hpp"
#include "db/store.hpp"
#include "schema.hpp"
#include "postgres/connection.hpp"

#include <memory>
#include <string>

namespace cutload::db::postgres {

// `url` must name a database holding cutload's tables when must_exist (std::invalid_argument
// otherwise).
std::unique_ptr<Store> open_store(const std::string& url, bool must_exist);

// The channel a process NOTIFYs when it queues a job (a new one, or one re-queued), on commit.
inline constexpr const char* kJobsChannel = "cutload_jobs";
void notify_job_queued(Connection& c);

class Runs final : public RunRepository {
public:
    explicit Runs(Connection& c) : c_(c) {}
    std::int64_t create(const NewRun& run) override;
    void set_upload_dir(std::int64_t id, const std::string& upload_dir) override;
    std::optional<RunRecord> get(std::int64_t id) override;
    std::optional<RunStatus> status(std::int64_t id) override;
    std::vector<RunRecord> list(const RunFilter& f) override;
    bool remove(std::int64_t id) override;
    bool upload_dir_in_use(const std::string& upload_dir) override;
    void add_block(std::int64_t run_id, std::int64_t idx, const std::string& body_json, bool flagged) override;
    void add_series_chunk(std::int64_t run_id, const SeriesChunkInfo& info, std::span<const unsigned char> data) override;
    void set_final_stock(std::int64_t run_id, std::uint64_t bytes, const std::function<void(std::ostream&)>& write) override;
    void set_program_body(std::int64_t run_id, const std::string& body_json) override;
    void mark_done(std::int64_t run_id, const std::string& summary_json, const std::string& block_names_json, bool flagged,
                   const std::string& finished_at) override;
    std::vector<BlockRow> blocks(std::int64_t run_id, std::int64_t from_idx, std::optional<bool> flagged,
                                 std::int64_t limit) override;
    std::vector<SeriesChunkInfo> series_index(std::int64_t run_id, int series) override;
    bool read_series_chunk(std::int64_t run_id, int series, int level, std::int64_t chunk,
                           const std::function<void(std::int64_t, std::span<const unsigned char>)>& use) override;
    bool has_final_stock(std::int64_t run_id) override;
    bool read_final_stock(std::int64_t run_id, const std::function<void(std::span<const unsigned char>)>& use) override;
    std::optional<std::string> program_body(std::int64_t run_id) override;
    std::optional<std::string> block_names(std::int64_t run_id) override;

private:
    Connection& c_;
};

class Optimizations final : public OptimizationRepository {
public:
    explicit Optimizations(Connection& c) : c_(c) {}
    std::int64_t create(std::int64_t run_id, const std::string& params_json, const std::string& created_at) override;
    std::optional<OptimizationRecord> get(std::int64_t id) override;
    std::optional<OptimizedProgram> program(std::int64_t id) override;
    std::vector<OptimizationRecord> of_run(std::int64_t run_id) override;
    std::vector<std::int64_t> ids_of_run(std::int64_t run_id, JobState state) override;
    bool remove_unless_running(std::int64_t id) override;
    bool mark_done(std::int64_t id, const std::string& result_json, const std::string& program,
                   const std::string& finished_at) override;

private:
    Connection& c_;
};

class Library final : public LibraryRepository {
public:
    explicit Library(Connection& c) : c_(c) {}
    std::vector<LibraryItem> list(LibraryKind k, std::int64_t after_id, const std::optional<std::string>& name,
                                  std::int64_t limit) override;
    std::optional<LibraryItem> get(LibraryKind k, std::int64_t id) override;
    std::optional<std::int64_t> find_by_name(LibraryKind k, const std::string& name) override;
    std::optional<std::int64_t> create(LibraryKind k, const std::string& name, const std::string& body_json,
                                       const std::string& now) override;
    LibraryWrite update(LibraryKind k, std::int64_t id, const std::string& name, const std::string& body_json,
                        const std::string& now) override;
    bool remove(LibraryKind k, std::int64_t id) override;

private:
    Connection& c_;
};

class Thresholds final : public ThresholdRepository {
public:
    explicit Thresholds(Connection& c) : c_(c) {}
    std::vector<ThresholdRecord> list() override;
    std::vector<ThresholdRecord> enabled() override;
    std::optional<ThresholdRecord> get(std::int64_t id) override;
    std::int64_t create(const ThresholdRule& r, const std::string& now) override;
    bool update(std::int64_t id, const ThresholdRule& r) override;
    bool remove(std::int64_t id) override;

private:
    Connection& c_;
};

class Alerts final : public AlertRepository {
public:
    explicit Alerts(Connection& c) : c_(c) {}
    std::int64_t create(std::int64_t run_id, std::optional<std::int64_t> threshold_id, const std::string& severity,
                        const std::string& body_json, const std::string& now) override;
    std::optional<AlertRecord> get(std::int64_t id) override;
    std::vector<AlertRecord> list(const AlertFilter& f) override;
    void acknowledge(std::int64_t id, const std::string& at, const std::string& by,
                     const std::optional<std::string>& note) override;

private:
    Connection& c_;
};

class Webhooks final : public WebhookRepository {
public:
    explicit Webhooks(Connection& c) : c_(c) {}
    std::vector<WebhookRecord> list() override;
    std::optional<WebhookRecord> get(std::int64_t id) override;
    std::int64_t create(const std::string& url, const std::optional<std::string>& secret, bool enabled,
                        const std::string& now) override;
    bool update(std::int64_t id, const std::string& url, const std::optional<std::string>& secret, bool enabled) override;
    bool remove(std::int64_t id) override;
    std::vector<std::int64_t> enabled_ids() override;
    void enqueue(std::int64_t webhook_id, std::int64_t alert_id, const std::string& payload, double next_attempt_unix,
                 const std::string& now) override;
    std::vector<DueDelivery> due(double now_unix, std::int64_t limit) override;
    void record_attempt(std::int64_t delivery_id, const DeliveryAttempt& a, DeliveryState state, double next_attempt_unix,
                        const std::optional<std::string>& delivered_at) override;
    std::vector<DeliveryRecord> deliveries(std::int64_t webhook_id, std::optional<std::int64_t> before_id,
                                           std::int64_t limit) override;
    std::optional<double> next_pending_unix() override;
    std::int64_t pending_count() override;

private:
    Connection& c_;
};

class ApiKeys final : public ApiKeyRepository {
public:
    explicit ApiKeys(Connection& c) : c_(c) {}
    void create(const std::string& hash, const std::string& prefix, const std::string& role,
                const std::optional<std::string>& name, const std::string& now) override;
    std::optional<ApiKeyRecord> find_by_hash(const std::string& hash) override;
    bool touch(const std::string& hash, const std::string& now) override;
    std::vector<ApiKeyRecord> list() override;
    std::vector<ApiKeyRecord> matching(const std::string& hash, const std::string& text) override;
    void revoke(std::int64_t id, const std::string& at) override;

private:
    Connection& c_;
};

class Jobs final : public JobRepository {
public:
    explicit Jobs(Connection& c) : c_(c) {}
    std::optional<std::int64_t> claim_oldest(const JobQueue& q, const std::string& now, const Lease& lease) override;
    std::vector<std::int64_t> renew_leases(const JobQueue& q, const std::string& token_prefix,
                                           const std::string& until) override;
    Requeued requeue_interrupted(const JobQueue& q, int max_attempts, const std::string& error,
                                 const std::string& now) override;
    Requeued requeue_expired(const JobQueue& q, int max_attempts, const std::string& error,
                             const std::string& now) override;
    bool holds(const JobQueue& q, std::int64_t id, const std::string& token) override;
    void finish(const JobQueue& q, std::int64_t id, JobState state, const std::optional<std::string>& error,
                const std::string& now, const std::optional<std::string>& token) override;
    bool cancel_running(const JobQueue& q, std::int64_t id, const std::string& now) override;
    bool cancel_queued(const JobQueue& q, std::int64_t id, const std::string& now) override;
    void set_progress(const JobQueue& q, std::int64_t id, double fraction) override;
    std::int64_t count(const JobQueue& q, std::initializer_list<JobState> states) override;

private:
    Connection& c_;
};

class LiveRuns final : public LiveRunRepository {
public:
    explicit LiveRuns(Connection& c) : c_(c) {}
    std::int64_t create(const NewRun& run, const std::string& source_json) override;
    std::optional<LiveRecord> get(std::int64_t run_id) override;
    std::vector<std::int64_t> open_runs() override;
    void update_status(std::int64_t run_id, const LiveStatusUpdate& u) override;
    std::int64_t add_chunk(std::int64_t run_id, double t0_s, double t1_s, std::int64_t n,
                           std::span<const unsigned char> data) override;
    std::vector<LiveChunk> chunks(std::int64_t run_id, std::int64_t after_seq, std::int64_t limit) override;
    void add_block(std::int64_t run_id, std::int64_t idx, const std::string& body_json, bool flagged) override;
    std::vector<BlockRow> blocks(std::int64_t run_id, std::int64_t from_idx) override;
    void close(std::int64_t run_id, const std::string& end_reason, const std::string& now) override;

private:
    Connection& c_;
};

class PgSession final : public Session {
public:
    explicit PgSession(const std::string& url) : c_(url) {}
    RunRepository& runs() override { return runs_; }
    OptimizationRepository& optimizations() override { return optimizations_; }
    LibraryRepository& library() override { return library_; }
    ThresholdRepository& thresholds() override { return thresholds_; }
    AlertRepository& alerts() override { return alerts_; }
    WebhookRepository& webhooks() override { return webhooks_; }
    ApiKeyRepository& api_keys() override { return api_keys_; }
    JobRepository& jobs() override { return jobs_; }
    LiveRunRepository& live() override { return live_; }
    Footprint reclaim_space() override;
    Connection& connection() { return c_; }

private:
    void begin_transaction() override;
    void commit_transaction() override;
    void rollback_transaction() noexcept override;

    Connection c_;
    int depth_ = 0;   // open transactions: 1 the outermost, more are savepoints within it
    Runs runs_{c_};
    Optimizations optimizations_{c_};
    Library library_{c_};
    Thresholds thresholds_{c_};
    Alerts alerts_{c_};
    Webhooks webhooks_{c_};
    ApiKeys api_keys_{c_};
    Jobs jobs_{c_};
    LiveRuns live_{c_};
};


}  // namespace cutload::db::postgres
