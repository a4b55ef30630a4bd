// The PostgreSQL backend's store and sessions: one database named by a libpq URL, one connection
// per session. Several processes may share the database: claims lock rows (jobs.cpp), migrations
// queue on an advisory lock (schema.cpp).
#include "postgres/store.hpp"

#include <fmt/format.h>

#include <chrono>
#include <thread>

namespace cutload::db::postgres {
namespace {

// LISTEN on a connection of its own. A connection lost is made again on the next wait.
class PgJobSignal final : public JobSignal {
public:
    explicit PgJobSignal(std::string url) : url_(std::move(url)) { listen(); }

    bool wait(double timeout_s) override {
        try {
            if (!c_) {
                listen();
                return true;   // a queued job may have gone unsignalled while it was down
            }
            return c_->wait_notification(timeout_s);
        } catch (const Error&) {
            c_.reset();
            // Not at once again: the server may be down for a while.
            std::this_thread::sleep_for(std::chrono::duration<double>(timeout_s));
            return false;
        }
    }

private:
    void listen() {
        c_ = std::make_unique<Connection>(url_);
        c_->exec(fmt::format("LISTEN {}", kJobsChannel));
    }
    std::string url_;
    std::unique_ptr<Connection> c_;
};

class PgStore final : public Store {
public:
    explicit PgStore(const std::string& url) : Store(url) {}

    int migrate() override {
        auto s = session();
        return postgres::migrate(static_cast<PgSession&>(*s).connection());
    }

    std::unique_ptr<JobSignal> job_signal() override { return std::make_unique<PgJobSignal>(location()); }

protected:
    std::unique_ptr<Session> connect() override { return std::make_unique<PgSession>(location()); }
};

std::int64_t database_bytes(Connection& c) {
    return c.run("SELECT pg_database_size(current_database())").i64(0, 0);
}

}  // namespace

std::unique_ptr<Store> open_store(const std::string& url, bool must_exist) {
    auto store = std::make_unique<PgStore>(url);
    // Connects now, so a bad URL, a refused connection or a wrong password fail here and not at
    // the first request.
    auto s = store->session();
    // Listing or revoking keys must not set cutload's tables up in a database named by mistake.
    if (must_exist && schema_version_of(static_cast<PgSession&>(*s).connection()) == 0)
        throw std::invalid_argument(fmt::format("no database at {} (it holds no cutload tables)", printable_location(url)));
    return store;
}

// VACUUM of the tables that hold run results (the bulk of the database) makes the space of deleted
// rows reusable and gives empty trailing pages back; it blocks neither readers nor writers, and
// pages untouched since the last one are skipped (the visibility map), so after a run is stored
// it costs about that run's size. The database's size is what it takes on disk. There is no
// write-ahead log of the store's own to empty: the server's WAL is PostgreSQL's business.
Session::Footprint PgSession::reclaim_space() {
    Footprint f;
    f.before_bytes = database_bytes(c_);
    c_.exec("VACUUM runs, run_blocks, series_chunks, run_stock, run_program, alerts, live_chunks, live_blocks");
    f.after_bytes = database_bytes(c_);
    f.wal_emptied = true;
    return f;
}

void PgSession::begin_transaction() {
    // READ COMMITTED: a claim's row lock (FOR UPDATE SKIP LOCKED) and a statement's own WHERE keep
    // the job states right; writers on different rows never wait for each other.
    c_.exec(depth_ == 0 ? std::string("BEGIN") : fmt::format("SAVEPOINT nested_{}", depth_));
    ++depth_;
}

void PgSession::commit_transaction() {
    if (c_.transaction_failed())
        throw Error("postgres: commit of a transaction in which a statement failed (it is rolled back)", Error::Kind::Other);
    c_.exec(depth_ == 1 ? std::string("COMMIT") : fmt::format("RELEASE nested_{}", depth_ - 1));
    --depth_;
}

void PgSession::rollback_transaction() noexcept {
    try {
        if (depth_ == 1)
            c_.exec("ROLLBACK");
        else
            c_.exec(fmt::format("ROLLBACK TO nested_{0}; RELEASE nested_{0}", depth_ - 1));
    } catch (const std::exception&) {
        // The connection is gone; the server rolled the transaction back.
    }
    --depth_;
}

}  // namespace cutload::db::postgres
