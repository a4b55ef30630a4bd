// The SQLite backend's store and sessions: one database file, WAL, one connection per session.
#include "sqlite/store.hpp"

#include <fmt/format.h>

#include <filesystem>

namespace cutload::db::sqlite {
namespace {

class SqliteStore final : public Store {
public:
    explicit SqliteStore(const std::string& path) : Store(path) {}

    int migrate() override {
        auto s = session();
        return sqlite::migrate(static_cast<SqliteSession&>(*s).connection());
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

std::string_view job_table(const JobQueue& q) {
    const bool plain = !q.name.empty() && q.name.find_first_not_of("abcdefghijklmnopqrstuvwxyz_0123456789") == std::string_view::npos;
    if (!plain) throw std::logic_error(fmt::format("job queue '{}' is not a table name", q.name));
    return q.name;
}

}  // namespace cutload::db::sqlite
