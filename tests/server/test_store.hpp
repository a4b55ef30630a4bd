// Shared by the server tests: where a test's store lives. The suite runs twice (tests/CMakeLists.txt):
// as "server: ..." on SQLite files in the test's temporary directory, and as "server-pg: ..." on
// PostgreSQL when CUTLOAD_TEST_PG_URL names a cluster (scripts/pg_test_cluster.sh): then every
// store_location() call creates a fresh database, dropped when the test process ends, so tests
// stay independent and may run two at a time. Sql runs a test's own statements on either.
#pragma once

#include <catch2/catch.hpp>
#include <libpq-fe.h>
#include <sqlite3.h>

#include <atomic>
#include <cstdlib>
#include <filesystem>
#include <mutex>
#include <random>
#include <string>
#include <unistd.h>
#include <vector>

namespace cutload::test {

// The admin URL of the test cluster (its "postgres" database); empty: the tests run on SQLite.
inline std::string pg_admin_url() {
    const char* u = std::getenv("CUTLOAD_TEST_PG_URL");
    return u ? u : "";
}
inline bool on_postgres() { return !pg_admin_url().empty(); }

// Skips the rest of a test that checks what only an SQLite file has (its size on disk, its WAL,
// PRAGMA user_version, file modes), saying so in the output.
#define CUTLOAD_SQLITE_ONLY(why)                                                   \
    do {                                                                           \
        if (::cutload::test::on_postgres()) {                                      \
            WARN("not on PostgreSQL: " << why);                                    \
            return;                                                                \
        }                                                                          \
    } while (0)

namespace detail {

// The URL with its database (the path after the authority) replaced by `db`.
inline std::string with_database(const std::string& url, const std::string& db) {
    const auto scheme_end = url.find("://");
    const auto query = url.find('?');
    const auto path = url.find('/', scheme_end == std::string::npos ? 0 : scheme_end + 3);
    const std::string head = url.substr(0, std::min(path, query));
    const std::string tail = query == std::string::npos ? "" : url.substr(query);
    return head + "/" + db + tail;
}

inline void admin_exec(const std::string& sql) {
    PGconn* c = PQconnectdb(pg_admin_url().c_str());
    if (PQstatus(c) != CONNECTION_OK) {
        const std::string msg = PQerrorMessage(c);
        PQfinish(c);
        throw std::runtime_error("test cluster at " + pg_admin_url() + ": " + msg);
    }
    PGresult* r = PQexec(c, sql.c_str());
    const bool ok = PQresultStatus(r) == PGRES_COMMAND_OK;
    const std::string msg = PQresultErrorMessage(r);
    PQclear(r);
    PQfinish(c);
    if (!ok) throw std::runtime_error(sql + ": " + msg);
}

// The databases this process made, dropped when it ends (after every store in it has closed).
struct Databases {
    std::mutex mu;
    std::vector<std::string> names;
    ~Databases() {
        for (const auto& n : names) {
            try {
                admin_exec("DROP DATABASE IF EXISTS " + n + " WITH (FORCE)");
            } catch (const std::exception&) {
                // The cluster is thrown away at the end of the run anyway.
            }
        }
    }
};

inline Databases& databases() {
    static Databases d;
    return d;
}

}  // namespace detail

// The store location for `file_name` in `dir`: that SQLite file, or a new, empty PostgreSQL
// database (one per call: a test that reopens a store keeps the location it got).
inline std::string store_location(const std::filesystem::path& dir, const std::string& file_name) {
    if (!on_postgres()) return (dir / file_name).string();
    static std::atomic<int> n{0};
    std::random_device rd;
    const std::string name = "cutload_t" + std::to_string(::getpid()) + "_" + std::to_string(++n) + "_" +
                             std::to_string(rd() % 100000);
    auto& dbs = detail::databases();
    {
        std::lock_guard lk(dbs.mu);
        dbs.names.push_back(name);
    }
    detail::admin_exec("CREATE DATABASE " + name + " TEMPLATE template0");
    return detail::with_database(pg_admin_url(), name);
}

// A test's own statements on a store location, outside the repositories (test-only job tables,
// rows from before a check). Portable SQL only, apart from id_column().
class Sql {
public:
    explicit Sql(const std::string& location) : pg_(location.find("://") != std::string::npos) {
        if (pg_) {
            pc_ = PQconnectdb(location.c_str());
            INFO(PQerrorMessage(pc_));
            REQUIRE(PQstatus(pc_) == CONNECTION_OK);
            PQexec(pc_, "SET client_min_messages = warning");
        } else {
            REQUIRE(sqlite3_open(location.c_str(), &h_) == SQLITE_OK);
            // The server's workers take the write lock for a moment now and then (claiming jobs).
            sqlite3_busy_timeout(h_, 10000);
        }
    }
    ~Sql() {
        if (pc_) PQfinish(pc_);
        if (h_) sqlite3_close(h_);
    }
    Sql(const Sql&) = delete;
    Sql& operator=(const Sql&) = delete;

    // An integer primary key the database numbers itself.
    std::string id_column() const {
        return pg_ ? "id BIGINT GENERATED BY DEFAULT AS IDENTITY PRIMARY KEY" : "id INTEGER PRIMARY KEY";
    }

    void exec(const std::string& sql) {
        if (pg_) {
            PGresult* r = PQexec(pc_, sql.c_str());
            INFO(sql << ": " << PQresultErrorMessage(r));
            const bool ok = PQresultStatus(r) == PGRES_COMMAND_OK || PQresultStatus(r) == PGRES_TUPLES_OK;
            PQclear(r);
            REQUIRE(ok);
            return;
        }
        char* err = nullptr;
        const int rc = sqlite3_exec(h_, sql.c_str(), nullptr, nullptr, &err);
        INFO(sql << ": " << (err ? err : ""));
        sqlite3_free(err);
        REQUIRE(rc == SQLITE_OK);
    }

    // The first column of the first row, as text ("" for none or NULL).
    std::string text(const std::string& sql) {
        std::string out;
        if (pg_) {
            PGresult* r = PQexec(pc_, sql.c_str());
            INFO(sql << ": " << PQresultErrorMessage(r));
            const bool ok = PQresultStatus(r) == PGRES_TUPLES_OK;
            if (ok && PQntuples(r) > 0 && !PQgetisnull(r, 0, 0)) out = PQgetvalue(r, 0, 0);
            PQclear(r);
            REQUIRE(ok);
            return out;
        }
        sqlite3_stmt* st = nullptr;
        INFO(sql << ": " << sqlite3_errmsg(h_));
        REQUIRE(sqlite3_prepare_v2(h_, sql.c_str(), -1, &st, nullptr) == SQLITE_OK);
        if (sqlite3_step(st) == SQLITE_ROW && sqlite3_column_type(st, 0) != SQLITE_NULL)
            out = reinterpret_cast<const char*>(sqlite3_column_text(st, 0));
        sqlite3_finalize(st);
        return out;
    }

private:
    bool pg_;
    PGconn* pc_ = nullptr;
    sqlite3* h_ = nullptr;
};

}  // namespace cutload::test
