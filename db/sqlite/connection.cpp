#include "sqlite/connection.hpp"

#include <fmt/format.h>
#include <sqlite3.h>

#include <streambuf>
#include <vector>


namespace cutload::db::sqlite {
namespace {

Error::Kind kind_of(int code) {
    switch (code & 0xff) {
        case SQLITE_CONSTRAINT: return Error::Kind::Constraint;
        case SQLITE_BUSY:
        case SQLITE_LOCKED: return Error::Kind::Busy;
        default: return Error::Kind::Other;
    }
}

[[noreturn]] void fail(sqlite3* db, int rc, std::string_view what) {
    const char* msg = db ? sqlite3_errmsg(db) : sqlite3_errstr(rc);
    throw Error(fmt::format("sqlite: {}: {}", what, msg), kind_of(db ? sqlite3_extended_errcode(db) : rc));
}

// std::streambuf into an open blob handle; a write past the blob's end fails the stream.
class BlobBuf : public std::streambuf {
public:
    BlobBuf(sqlite3_blob* blob, std::uint64_t bytes) : blob_(blob), bytes_(bytes), buf_(1 << 20) {
        setp(buf_.data(), buf_.data() + buf_.size());
    }
    std::uint64_t written() const { return at_; }

protected:
    int_type overflow(int_type c) override {
        if (!drain()) return traits_type::eof();
        if (!traits_type::eq_int_type(c, traits_type::eof())) {
            *pptr() = traits_type::to_char_type(c);
            pbump(1);
        }
        return traits_type::not_eof(c);
    }
    int sync() override { return drain() ? 0 : -1; }

private:
    bool drain() {
        const std::uint64_t n = static_cast<std::uint64_t>(pptr() - pbase());
        if (n == 0) return true;
        if (at_ + n > bytes_ || sqlite3_blob_write(blob_, pbase(), static_cast<int>(n), static_cast<int>(at_)) != SQLITE_OK)
            return false;
        at_ += n;
        setp(buf_.data(), buf_.data() + buf_.size());
        return true;
    }
    sqlite3_blob* blob_;
    std::uint64_t bytes_, at_ = 0;
    std::vector<char> buf_;
};

}  // namespace

Stmt::Stmt(sqlite3* db, std::string_view sql) : db_(db), st_(nullptr) {
    int rc = sqlite3_prepare_v2(db, sql.data(), static_cast<int>(sql.size()), &st_, nullptr);
    if (rc != SQLITE_OK) fail(db, rc, fmt::format("prepare \"{}\"", sql));
}

Stmt::Stmt(sqlite3* db, sqlite3_stmt* st, bool* in_use) : db_(db), st_(st), in_use_(in_use) {}

Stmt::Stmt(Stmt&& o) noexcept : db_(o.db_), st_(o.st_), in_use_(o.in_use_) { o.st_ = nullptr; }

Stmt::~Stmt() {
    if (!st_) return;
    if (!in_use_) {
        sqlite3_finalize(st_);
        return;
    }
    // A statement left un-reset keeps its read transaction open, which would stop WAL checkpoints.
    sqlite3_reset(st_);
    sqlite3_clear_bindings(st_);
    *in_use_ = false;
}

Stmt& Stmt::bind(int i, std::int64_t v) {
    if (int rc = sqlite3_bind_int64(st_, i, v); rc != SQLITE_OK) fail(db_, rc, "bind");
    return *this;
}
Stmt& Stmt::bind(int i, double v) {
    if (int rc = sqlite3_bind_double(st_, i, v); rc != SQLITE_OK) fail(db_, rc, "bind");
    return *this;
}
Stmt& Stmt::bind(int i, std::string_view v) {
    int rc = sqlite3_bind_text64(st_, i, v.data(), v.size(), SQLITE_TRANSIENT, SQLITE_UTF8);
    if (rc != SQLITE_OK) fail(db_, rc, "bind");
    return *this;
}
Stmt& Stmt::bind_blob(int i, const void* data, std::size_t bytes) {
    if (int rc = sqlite3_bind_blob64(st_, i, data, bytes, SQLITE_TRANSIENT); rc != SQLITE_OK) fail(db_, rc, "bind");
    return *this;
}
Stmt& Stmt::bind_null(int i) {
    if (int rc = sqlite3_bind_null(st_, i); rc != SQLITE_OK) fail(db_, rc, "bind");
    return *this;
}

bool Stmt::step() {
    int rc = sqlite3_step(st_);
    if (rc == SQLITE_ROW) return true;
    if (rc == SQLITE_DONE) return false;
    fail(db_, rc, "step");
}

void Stmt::run() {
    while (step()) {
    }
}

void Stmt::reset() {
    sqlite3_reset(st_);
}

bool Stmt::is_null(int col) const { return sqlite3_column_type(st_, col) == SQLITE_NULL; }
std::int64_t Stmt::i64(int col) const { return sqlite3_column_int64(st_, col); }
double Stmt::real(int col) const { return sqlite3_column_double(st_, col); }
std::string Stmt::text(int col) const {
    auto* p = reinterpret_cast<const char*>(sqlite3_column_text(st_, col));
    return p ? std::string(p, static_cast<std::size_t>(sqlite3_column_bytes(st_, col))) : std::string();
}
std::optional<std::string> Stmt::opt_text(int col) const {
    if (is_null(col)) return std::nullopt;
    return text(col);
}
std::optional<std::int64_t> Stmt::opt_i64(int col) const {
    if (is_null(col)) return std::nullopt;
    return i64(col);
}
std::optional<double> Stmt::opt_real(int col) const {
    if (is_null(col)) return std::nullopt;
    return real(col);
}
std::span<const unsigned char> Stmt::blob(int col) const {
    const auto* p = static_cast<const unsigned char*>(sqlite3_column_blob(st_, col));
    return {p, static_cast<std::size_t>(sqlite3_column_bytes(st_, col))};
}

Connection::Connection(const std::string& path, int busy_timeout_ms) {
    int flags = SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_NOMUTEX;
    int rc = sqlite3_open_v2(path.c_str(), &db_, flags, nullptr);
    if (rc != SQLITE_OK) {
        std::string msg = db_ ? sqlite3_errmsg(db_) : sqlite3_errstr(rc);
        sqlite3_close(db_);
        db_ = nullptr;
        throw Error(fmt::format("cannot open database {}: {}", path, msg), kind_of(rc));
    }
    sqlite3_busy_timeout(db_, busy_timeout_ms);
    // NORMAL is durable across application crashes in WAL mode (only power loss can lose the
    // last commits), which is the guarantee the job store needs.
    // The WAL is checkpointed into the file every kWalAutocheckpointPages pages (SQLite's default,
    // stated) and cut back to kJournalSizeLimitBytes after each checkpoint; it grows beyond that
    // only while one transaction (one run's results) or a long reader holds it.
    exec(fmt::format("PRAGMA journal_mode=WAL; PRAGMA synchronous=NORMAL; PRAGMA foreign_keys=ON; "
                     "PRAGMA wal_autocheckpoint={}; PRAGMA journal_size_limit={};",
                     kWalAutocheckpointPages, kJournalSizeLimitBytes));
}

Connection::~Connection() {
    for (auto& [sql, c] : cache_) sqlite3_finalize(c.st);
    sqlite3_close_v2(db_);
}

Stmt Connection::prepare(std::string_view sql) {
    auto it = cache_.find(std::string(sql));
    if (it != cache_.end()) {
        if (it->second.in_use) return Stmt(db_, sql);   // nested use of the same text
        it->second.in_use = true;
        return Stmt(db_, it->second.st, &it->second.in_use);
    }
    if (cache_.size() >= kMaxCached) return Stmt(db_, sql);
    sqlite3_stmt* st = nullptr;
    int rc = sqlite3_prepare_v3(db_, sql.data(), static_cast<int>(sql.size()), SQLITE_PREPARE_PERSISTENT, &st, nullptr);
    if (rc != SQLITE_OK) fail(db_, rc, fmt::format("prepare \"{}\"", sql));
    auto& c = cache_.emplace(std::string(sql), Cached{st, true}).first->second;
    return Stmt(db_, st, &c.in_use);
}

void Connection::exec(std::string_view sql) {
    std::string s(sql);
    char* err = nullptr;
    int rc = sqlite3_exec(db_, s.c_str(), nullptr, nullptr, &err);
    if (rc != SQLITE_OK) {
        std::string msg = err ? err : sqlite3_errstr(rc);
        sqlite3_free(err);
        throw Error(fmt::format("sqlite: {}", msg), kind_of(sqlite3_extended_errcode(db_)));
    }
}

void Connection::set_busy_timeout(int ms) { sqlite3_busy_timeout(db_, ms); }

std::int64_t Connection::last_insert_id() const { return sqlite3_last_insert_rowid(db_); }
int Connection::changes() const { return sqlite3_changes(db_); }

void Connection::write_blob(const char* table, const char* column, std::int64_t rowid, std::uint64_t bytes,
                            const std::function<void(std::ostream&)>& write) {
    if (bytes > static_cast<std::uint64_t>(sqlite3_limit(db_, SQLITE_LIMIT_LENGTH, -1)))
        throw Error(fmt::format("sqlite: a {} value of {} bytes is over the length limit", column, bytes), Error::Kind::Other);
    sqlite3_blob* blob = nullptr;
    if (int rc = sqlite3_blob_open(db_, "main", table, column, rowid, 1, &blob); rc != SQLITE_OK) {
        sqlite3_blob_close(blob);
        fail(db_, rc, fmt::format("open {}.{} of row {}", table, column, rowid));
    }
    struct Close {
        sqlite3_blob* b;
        ~Close() { sqlite3_blob_close(b); }
    } close{blob};
    BlobBuf buf(blob, bytes);
    std::ostream out(&buf);
    write(out);
    out.flush();
    if (!out || buf.written() != bytes)
        throw Error(fmt::format("sqlite: writing {}.{} of row {}: {} of {} bytes came", table, column, rowid, buf.written(),
                                bytes),
                    Error::Kind::Other);
}

ImmediateTransaction::~ImmediateTransaction() {
    if (!open_) return;
    try {
        c_.exec("ROLLBACK");
    } catch (const Error&) {
        // Already rolled back by SQLite itself (e.g. after SQLITE_FULL).
    }
}

void ImmediateTransaction::commit() {
    c_.exec("COMMIT");
    open_ = false;
}

Savepoint::Savepoint(Connection& c, const char* name) : c_(c), name_(name) { c_.exec(fmt::format("SAVEPOINT {}", name_)); }

Savepoint::~Savepoint() {
    if (!open_) return;
    try {
        c_.exec(fmt::format("ROLLBACK TO {0}; RELEASE {0}", name_));
    } catch (const Error&) {
        // Already rolled back by SQLite itself.
    }
}

void Savepoint::release() {
    c_.exec(fmt::format("RELEASE {}", name_));
    open_ = false;
}

}  // namespace cutload::db::sqlite
