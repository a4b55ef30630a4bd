// Public interface of db: cutload's store, behind repositories.
//
// A Store is opened from a location ("path/to/cutload.db": an SQLite file). It hands out Sessions
// from a pool; a Session is one connection to the store, used by one thread at a time, and gives
// the repositories: one per aggregate, each exposing value types and operations and nothing of the
// backend (no SQL, no statements, no backend types). Every dialect-specific piece (placeholders,
// RETURNING, AUTOINCREMENT, blobs, PRAGMAs, busy handling, the schema's DDL) lives in the
// backend's own files (db/sqlite/), so a second backend implements Store, Session and the
// repository interfaces and nothing above this layer changes. See docs/architecture.md.
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

namespace cutload::db {

class RunRepository;
class OptimizationRepository;
class LibraryRepository;
class ThresholdRepository;
class AlertRepository;
class WebhookRepository;
class ApiKeyRepository;
class JobRepository;
class LiveRunRepository;

// A failed store operation. Constraint: the store refused the change (a unique name, a foreign
// key, a check); a caller may answer it as a conflict. Busy: another writer held the store for
// longer than the backend waits. Everything else is Other.
class Error : public std::runtime_error {
public:
    enum class Kind { Constraint, Busy, Other };
    Error(const std::string& what, Kind kind) : std::runtime_error(what), kind_(kind) {}
    Kind kind() const { return kind_; }
    bool is_constraint() const { return kind_ == Kind::Constraint; }

private:
    Kind kind_;
};

// One connection to the store. Not shared between threads; leased from Store::session().
class Session {
public:
    virtual ~Session() = default;

    virtual RunRepository& runs() = 0;
    virtual OptimizationRepository& optimizations() = 0;
    virtual LibraryRepository& library() = 0;
    virtual ThresholdRepository& thresholds() = 0;
    virtual AlertRepository& alerts() = 0;
    virtual WebhookRepository& webhooks() = 0;
    virtual ApiKeyRepository& api_keys() = 0;
    virtual JobRepository& jobs() = 0;
    virtual LiveRunRepository& live() = 0;

    // Gives the space that deletions freed back to the file system and empties the write-ahead
    // log, so a DELETE shrinks what the store takes on disk. Outside any transaction; takes the
    // write lock for as long as freeing takes (about proportional to what was freed). Returns
    // the bytes the store's files took before and after.
    struct Footprint {
        std::int64_t before_bytes = 0, after_bytes = 0;
        bool wal_emptied = false;   // false: a reader kept the log (the next checkpoint catches up)
    };
    virtual Footprint reclaim_space() = 0;

protected:
    friend class Transaction;
    // A write transaction; begun inside another one it is a nested savepoint of it.
    virtual void begin_transaction() = 0;
    virtual void commit_transaction() = 0;
    virtual void rollback_transaction() noexcept = 0;
};

// Rolls back unless commit() was called. Write transactions take the write lock at begin, so two
// writers queue instead of one failing half-way.
class Transaction {
public:
    explicit Transaction(Session& s) : s_(s) { s_.begin_transaction(); }
    Transaction(const Transaction&) = delete;
    Transaction& operator=(const Transaction&) = delete;
    ~Transaction() {
        if (open_) s_.rollback_transaction();
    }
    void commit() {
        s_.commit_transaction();
        open_ = false;
    }

private:
    Session& s_;
    bool open_ = true;
};

class Store;

// A session borrowed from a store's pool; given back when destroyed.
class SessionLease {
public:
    SessionLease(Store& store, std::unique_ptr<Session> s) : store_(&store), s_(std::move(s)) {}
    SessionLease(SessionLease&&) = default;
    SessionLease& operator=(SessionLease&&) = delete;
    ~SessionLease();
    Session& operator*() { return *s_; }
    Session* operator->() { return s_.get(); }

private:
    Store* store_;
    std::unique_ptr<Session> s_;
};

// Tells a process that another one queued a job (PostgreSQL's LISTEN/NOTIFY, on a connection of
// its own), so idle workers start at once rather than at their next look at the queue. Used by
// one thread.
class JobSignal {
public:
    virtual ~JobSignal() = default;
    // Waits up to timeout_s; true when a job was queued (or re-queued) since the last call. A lost
    // connection is made again and answers true once (a signal may have been missed meanwhile).
    virtual bool wait(double timeout_s) = 0;
};

class Store {
public:
    enum class Open { CreateIfMissing, MustExist };

    // "path/to/cutload.db" (or any location without a scheme) opens an SQLite file;
    // "postgresql://user:password@host:port/database?..." (or "postgres://...": a libpq URL)
    // connects to PostgreSQL, whose database must exist (CreateIfMissing creates cutload's tables
    // in it at migrate()). MustExist throws std::invalid_argument "no database at <location>"
    // rather than creating one (PostgreSQL: a database without cutload's tables).
    static std::unique_ptr<Store> open(const std::string& location, Open mode = Open::CreateIfMissing);

    Store(const Store&) = delete;
    Store& operator=(const Store&) = delete;
    virtual ~Store() = default;

    // Brings the schema to schema_version(), in place; idempotent. Returns the version reached.
    virtual int migrate() = 0;
    const std::string& location() const { return location_; }

    // A pooled session: an idle one, or a new connection.
    SessionLease session();

    // Signals of jobs queued by other processes; null where only one process uses the store
    // (SQLite: the server wakes its own workers).
    virtual std::unique_ptr<JobSignal> job_signal() { return nullptr; }

protected:
    explicit Store(std::string location) : location_(std::move(location)) {}
    virtual std::unique_ptr<Session> connect() = 0;

private:
    friend class SessionLease;
    void give_back(std::unique_ptr<Session> s);

    std::string location_;
    std::mutex mu_;
    std::vector<std::unique_ptr<Session>> idle_;
};

// The schema version this build migrates to. One numbered sequence of schema changes for every
// backend: version N means the same tables and columns whatever the dialect.
int schema_version();

// Which backend a location names: a postgresql:// or postgres:// URL, else an SQLite file (a
// path without a scheme). Throws std::invalid_argument for any other scheme.
enum class Backend { Sqlite, Postgres };
Backend backend_of(const std::string& location);

// The location as messages and logs may show it: a URL's password replaced by "***" (in
// "user:password@" and in a "password=" parameter); an SQLite path as it is.
std::string printable_location(const std::string& location);

// UTC "YYYY-MM-DDTHH:MM:SS.sssZ", the form of every stored time: such texts sort as the times do.
std::string iso_time(std::chrono::system_clock::time_point t);
std::string now_iso();

}  // namespace cutload::db
