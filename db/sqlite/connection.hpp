// Private to db: a thin, exception-based wrapper over SQLite for the SQLite backend.
//
// One Connection per thread at a time (SQLite connections are not shared between threads here);
// WAL mode lets many readers run beside the one writer. Write transactions start IMMEDIATE so two
// writers queue on the busy timeout instead of failing half-way with SQLITE_BUSY.
#pragma once

#include "db/store.hpp"

#include <cstdint>
#include <functional>
#include <optional>
#include <ostream>
#include <span>
#include <string>
#include <string_view>
#include <unordered_map>

struct sqlite3;
struct sqlite3_stmt;

namespace cutload::db::sqlite {

class Stmt {
public:
    Stmt(sqlite3* db, std::string_view sql);
    // A statement borrowed from a connection's cache: reset, and *in_use cleared, when destroyed.
    Stmt(sqlite3* db, sqlite3_stmt* st, bool* in_use);
    Stmt(Stmt&& o) noexcept;
    Stmt(const Stmt&) = delete;
    Stmt& operator=(const Stmt&) = delete;
    ~Stmt();

    // Parameters are 1-based like SQLite's; each returns *this so calls chain.
    Stmt& bind(int i, std::int64_t v);
    Stmt& bind(int i, int v) { return bind(i, static_cast<std::int64_t>(v)); }
    Stmt& bind(int i, bool v) { return bind(i, static_cast<std::int64_t>(v ? 1 : 0)); }
    Stmt& bind(int i, double v);
    Stmt& bind(int i, std::string_view v);
    Stmt& bind(int i, const char* v) { return bind(i, std::string_view(v)); }
    Stmt& bind(int i, const std::string& v) { return bind(i, std::string_view(v)); }
    Stmt& bind_blob(int i, const void* data, std::size_t bytes);
    Stmt& bind_null(int i);
    template <class T>
    Stmt& bind(int i, const std::optional<T>& v) { return v ? bind(i, *v) : bind_null(i); }

    bool step();     // true: a row is ready; false: done
    void run();      // steps to completion, for statements without rows
    void reset();    // ready to step again with the same bindings

    bool is_null(int col) const;
    std::int64_t i64(int col) const;
    double real(int col) const;
    std::string text(int col) const;
    std::optional<std::string> opt_text(int col) const;
    std::optional<std::int64_t> opt_i64(int col) const;
    std::optional<double> opt_real(int col) const;
    // Borrowed until the next step/reset.
    std::span<const unsigned char> blob(int col) const;

private:
    sqlite3* db_;
    sqlite3_stmt* st_;
    bool* in_use_ = nullptr;   // set: borrowed from a connection's cache
};

// How long a connection waits for another writer before SQLITE_BUSY.
constexpr int kBusyTimeoutMs = 10000;
// The write-ahead log's bound (docs/api.md, "Disk"): checkpointed every 1000 pages (4 MiB at
// the 4 KiB page) and truncated to 64 MiB after a checkpoint that leaves it larger.
constexpr int kWalAutocheckpointPages = 1000;
constexpr long long kJournalSizeLimitBytes = 64LL << 20;

class Connection {
public:
    // Opens (creating if needed), sets WAL, foreign keys and the busy timeout.
    explicit Connection(const std::string& path, int busy_timeout_ms = kBusyTimeoutMs);
    Connection(const Connection&) = delete;
    Connection& operator=(const Connection&) = delete;
    ~Connection();

    void exec(std::string_view sql);   // one or more statements, no rows
    // Compiled once per connection and reused: the same SQL text gets the cached statement
    // (reset, bindings cleared) unless it is still in use, then a fresh one.
    Stmt prepare(std::string_view sql);
    void set_busy_timeout(int ms);
    std::int64_t last_insert_id() const;
    int changes() const;
    // Fills the blob `column` of row `rowid` in `table`, created beforehand as zeroblob(bytes), with
    // what `write` puts into the stream, in pieces as it comes: a value of tens of MB (a stock) is
    // never held whole, by the caller or by SQLite. Throws unless exactly `bytes` bytes came.
    void write_blob(const char* table, const char* column, std::int64_t rowid, std::uint64_t bytes,
                    const std::function<void(std::ostream&)>& write);

private:
    struct Cached {
        sqlite3_stmt* st = nullptr;
        bool in_use = false;
    };
    // Bounded: every statement cutload runs is one of a few dozen fixed texts (a few per job queue).
    static constexpr std::size_t kMaxCached = 128;
    sqlite3* db_ = nullptr;
    std::unordered_map<std::string, Cached> cache_;
};

// BEGIN IMMEDIATE .. COMMIT on a bare connection (migrations); rolls back unless committed.
class ImmediateTransaction {
public:
    explicit ImmediateTransaction(Connection& c) : c_(c) { c_.exec("BEGIN IMMEDIATE"); }
    ImmediateTransaction(const ImmediateTransaction&) = delete;
    ImmediateTransaction& operator=(const ImmediateTransaction&) = delete;
    ~ImmediateTransaction();
    void commit();

private:
    Connection& c_;
    bool open_ = true;
};

// Makes the statements until release() one atomic step, inside a transaction or on its own (a
// savepoint outside any transaction is one); rolled back to its start unless released.
class Savepoint {
public:
    Savepoint(Connection& c, const char* name);
    Savepoint(const Savepoint&) = delete;
    Savepoint& operator=(const Savepoint&) = delete;
    ~Savepoint();
    void release();

private:
    Connection& c_;
    std::string name_;
    bool open_ = true;
};

// Brings the database to the newest schema version (PRAGMA user_version); idempotent.
// Returns the version reached.
int migrate(Connection& c);

}  // namespace cutload::db::sqlite
