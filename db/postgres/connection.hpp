// Private to db: a thin, exception-based wrapper over libpq for the PostgreSQL backend.
//
// One Connection per session (libpq connections are not shared between threads here). Every
// statement is prepared once per connection (named by its SQL text) and run with binary
// parameters and binary results: no text formatting of numbers on the way in or out, and blobs
// (series chunks, the final stock) travel as their bytes.
#pragma once

#include "db/store.hpp"

#include <cstdint>
#include <deque>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <type_traits>
#include <unordered_map>
#include <vector>

struct pg_conn;
struct pg_result;

namespace cutload::db::postgres {

// Statement parameters, $1 .. $n in the order added. Text and blobs are borrowed: they must
// outlive the statement's run (a final stock of tens of megabytes is not copied).
class Params {
public:
    Params& add(std::int64_t v);
    Params& add(int v) { return add(static_cast<std::int64_t>(v)); }
    Params& add(bool v);
    Params& add(double v);
    Params& add(std::string_view v);
    Params& add(const char* v) { return add(std::string_view(v)); }
    Params& add(const std::string& v) { return add(std::string_view(v)); }
    Params& add_blob(std::span<const unsigned char> bytes);
    Params& add_blob(std::string_view bytes);
    template <class T>
    Params& add(const std::optional<T>& v) {
        if (v) return add(*v);
        return add_null(type_of<T>());
    }

    std::size_t size() const { return values_.size(); }
    const std::vector<unsigned>& types() const { return types_; }
    const char* const* values() const { return values_.data(); }
    const int* lengths() const { return lengths_.data(); }
    const int* formats() const { return formats_.data(); }

private:
    template <class T>
    static unsigned type_of();
    Params& add_null(unsigned type);
    Params& push(unsigned type, const char* data, std::size_t bytes);
    Params& push_owned(unsigned type, std::string bytes);

    std::vector<unsigned> types_;
    std::vector<const char*> values_;
    std::vector<int> lengths_, formats_;
    std::deque<std::string> owned_;   // a deque: adding never moves what earlier values point at
};

// A statement's rows (binary format), read by row and column; columns decode by their type.
class Result {
public:
    explicit Result(pg_result* r) : r_(r) {}
    Result(Result&& o) noexcept : r_(o.r_) { o.r_ = nullptr; }
    Result(const Result&) = delete;
    Result& operator=(const Result&) = delete;
    ~Result();

    int rows() const;
    bool empty() const { return rows() == 0; }
    std::int64_t affected() const;   // rows an INSERT, UPDATE or DELETE changed

    bool is_null(int row, int col) const;
    std::int64_t i64(int row, int col) const;
    double real(int row, int col) const;
    bool boolean(int row, int col) const;
    std::string text(int row, int col) const;
    std::optional<std::string> opt_text(int row, int col) const;
    std::optional<std::int64_t> opt_i64(int row, int col) const;
    std::optional<double> opt_real(int row, int col) const;
    // Valid while this Result lives.
    std::span<const unsigned char> blob(int row, int col) const;

private:
    const char* raw(int row, int col, std::size_t& bytes) const;
    pg_result* r_;
};

class Connection {
public:
    // Connects (libpq URL or keyword string). Failures throw Error naming the store, without
    // its password, and what libpq said, on one line.
    explicit Connection(const std::string& url);
    Connection(const Connection&) = delete;
    Connection& operator=(const Connection&) = delete;
    ~Connection();

    // One or more statements without parameters (DDL, BEGIN, SAVEPOINT ...).
    void exec(std::string_view sql);
    // One statement, prepared on first use on this connection and reused.
    Result run(std::string_view sql, const Params& p = {});
    bool in_transaction() const;
    // After LISTEN: waits up to timeout_s for notifications; true when at least one arrived (all
    // that did are consumed). Throws Error when the connection is lost.
    bool wait_notification(double timeout_s);
    // A statement of the open transaction failed: PostgreSQL would answer COMMIT by rolling back.
    bool transaction_failed() const;

private:
    [[noreturn]] void fail(pg_result* r, std::string_view what);
    void reconnect_if_lost();

    pg_conn* conn_ = nullptr;
    std::string url_;
    std::unordered_map<std::string, std::string> prepared_;   // SQL text -> statement name
};

// Runs `f` so that a failing statement inside an open transaction does not abort that
// transaction (PostgreSQL's rule, unlike SQLite's): a savepoint around it, rolled back on error.
template <class F>
auto guarded(Connection& c, F&& f) -> decltype(f()) {
    if (!c.in_transaction()) return f();
    c.exec("SAVEPOINT cutload_guard");
    try {
        if constexpr (std::is_void_v<decltype(f())>) {
            f();
            c.exec("RELEASE cutload_guard");
        } else {
            auto out = f();
            c.exec("RELEASE cutload_guard");
            return out;
        }
    } catch (...) {
        c.exec("ROLLBACK TO cutload_guard; RELEASE cutload_guard");
        throw;
    }
}

template <>
inline unsigned Params::type_of<std::int64_t>() { return 20; }   // int8
template <>
inline unsigned Params::type_of<int>() { return 20; }
template <>
inline unsigned Params::type_of<bool>() { return 16; }           // bool
template <>
inline unsigned Params::type_of<double>() { return 701; }        // float8
template <>
inline unsigned Params::type_of<std::string>() { return 25; }    // text

// Brings the database to the newest schema version; idempotent, and safe when several processes
// start at once (they queue on an advisory lock). Returns the version reached.
int migrate(Connection& c);
// The version the database holds; 0 when cutload's tables are not there.
int schema_version_of(Connection& c);

}  // namespace cutload::db::postgres
