// The SQLite backend's store and sessions: one database file, WAL, one connection per session.
#include "sqlite/store.hpp"

#include <fmt/format.h>

#include <chrono>
#include <filesystem>
#include <thread>

namespace cutload::db::sqlite {
namespace {

std::int64_t pragma_int(Connection& c, const char* pragma) {
    auto st = c.prepare(fmt::format("PRAGMA {}", pragma));
    st.step();
    return st.i64(0);
}

// Freed pages are given back by `PRAGMA incremental_vacuum` (reclaim_space) only in a file with
// auto_vacuum = INCREMENTAL. A new file takes it before its first table; a file made by an older
// cutload is rebuilt once by VACUUM (a copy of the live data: it needs that much free disk).
void use_incremental_vacuum(Connection& c) {
    constexpr int kIncremental = 2;
    if (pragma_int(c, "auto_vacuum") == kIncremental) return;
    c.exec("PRAGMA auto_vacuum=INCREMENTAL");
    if (pragma_int(c, "auto_vacuum") == kIncremental) return;   // empty file: set, nothing to rebuild
    c.exec("VACUUM");
}

std::int64_t file_bytes(const std::string& path) {
    std::error_code ec;
    const auto n = std::filesystem::file_size(path, ec);
    return ec ? 0 : static_cast<std::int64_t>(n);
}

std::int64_t footprint_bytes(const std::string& path) { return file_bytes(path) + file_bytes(path + "-wal"); }

class SqliteStore final : public Store {
public:
    explicit SqliteStore(const std::string& path) : Store(path) {}

    int migrate() override {
        auto s = session();
        Connection& c = static_cast<SqliteSession&>(*s).connection();
        use_incremental_vacuum(c);
        return sqlite::migrate(c);
    }

protected:
    std::unique_ptr<Session> connect() override { return std::make_unique<SqliteSession>(location()); }
};

}  // namespace

std::unique_ptr<Store> open_store(const std::string& path, bool must_exist) {
    // Listing or revoking keys must not create a database because of a typo in its path.
    if (must_exist && !std::filesystem::exists(path)) throw std::invalid_argument(fmt::format("no database at {}", path));
    auto store = std::make_unique<SqliteStore>(path);
    store->session();   // opens the file now, so a bad path fails here and not at the first request
    return store;
}

Session::Footprint SqliteSession::reclaim_space() {
    Footprint f;
    f.before_bytes = footprint_bytes(path_);
    c_.exec("PRAGMA incremental_vacuum");
    // TRUNCATE: the log is emptied to zero bytes once every reader has moved past it. A job
    // worker's claim or the webhook sender may hold the log for a moment (SQLite answers busy
    // at once rather than waiting for them), so a few tries; one still busy after them leaves
    // the log as it is and the next checkpoint catches up.
    constexpr int kTries = 40;
    constexpr auto kPause = std::chrono::milliseconds(25);
    for (int i = 0; i < kTries && !f.wal_emptied; ++i) {
        if (i > 0) std::this_thread::sleep_for(kPause);
        auto st = c_.prepare("PRAGMA wal_checkpoint(TRUNCATE)");
        if (st.step()) f.wal_emptied = st.i64(0) == 0;   // the row: busy, frames in the log, frames checkpointed
    }
    f.after_bytes = footprint_bytes(path_);
    return f;
}

void SqliteSession::begin_transaction() {
    // The outermost takes the write lock at once (IMMEDIATE); inner ones are savepoints of it.
    c_.exec(depth_ == 0 ? std::string("BEGIN IMMEDIATE") : fmt::format("SAVEPOINT nested_{}", depth_));
    ++depth_;
}

void SqliteSession::commit_transaction() {
    c_.exec(depth_ == 1 ? std::string("COMMIT") : fmt::format("RELEASE nested_{}", depth_ - 1));
    --depth_;
}

void SqliteSession::rollback_transaction() noexcept {
    try {
        if (depth_ == 1)
            c_.exec("ROLLBACK");
        else
            c_.exec(fmt::format("ROLLBACK TO nested_{0}; RELEASE nested_{0}", depth_ - 1));
    } catch (const std::exception&) {
        // Already rolled back by SQLite itself (e.g. after SQLITE_FULL).
    }
    --depth_;
}

}  // namespace cutload::db::sqlite
