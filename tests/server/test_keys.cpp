// API key management through the real binary: `cutload keys list` shows what a key is without
// the key, `cutload keys revoke` shuts a key out with a 401 at once.
#include "db/store.hpp"
#include "harness.hpp"


#include <cstdio>
#include <sys/wait.h>

using namespace cutload::test;

namespace {

struct CliResult {
    int status = -1;
    std::string out;   // stdout and stderr
};

CliResult run_cli(const std::string& args) {
    CliResult r;
    FILE* p = ::popen((std::string(CUTLOAD_BINARY) + " " + args + " 2>&1").c_str(), "r");
    REQUIRE(p);
    char buf[4096];
    while (std::size_t n = std::fread(buf, 1, sizeof buf, p)) r.out.append(buf, n);
    const int st = ::pclose(p);
    r.status = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
    return r;
}

const cutload::server::ApiKeyInfo& key_with_prefix(const std::vector<cutload::server::ApiKeyInfo>& keys,
                                                   const std::string& key) {
    for (const auto& k : keys)
        if (k.prefix == key.substr(0, 10)) return k;
    FAIL("no key listed with the prefix of " << key.substr(0, 10));
    throw std::logic_error("unreachable");
}

}  // namespace

TEST_CASE("keys: list shows prefix role name and last use but never the key, and revoke answers 401 with a JSON error") {
    TestServer ts;
    const std::string db = ts.opt.db_path;

    auto keys = cutload::server::list_api_keys(db);
    REQUIRE(keys.size() == 3);
    const auto& reader = key_with_prefix(keys, ts.read_key);
    REQUIRE(reader.role == cutload::server::Role::Read);
    REQUIRE(reader.name == "test reader");
    REQUIRE_FALSE(reader.last_used_at);
    REQUIRE_FALSE(reader.revoked_at);

    auto rc = ts.client(ts.read_key);
    REQUIRE(rc.Get("/api/v1/runs")->status == 200);
    keys = cutload::server::list_api_keys(db);
    REQUIRE(key_with_prefix(keys, ts.read_key).last_used_at);
    REQUIRE_FALSE(key_with_prefix(keys, ts.write_key).last_used_at);

    CliResult list = run_cli("keys list --db " + db);
    INFO(list.out);
    REQUIRE(list.status == 0);
    for (const auto& k : {ts.admin_key, ts.write_key, ts.read_key}) {
        REQUIRE(list.out.find(k.substr(0, 10)) != std::string::npos);
        REQUIRE(list.out.find(k) == std::string::npos);   // the secret part never appears
    }
    REQUIRE(list.out.find("test writer") != std::string::npos);
    REQUIRE(list.out.find("LAST USED") != std::string::npos);

    CliResult revoke = run_cli("keys revoke " + ts.read_key.substr(0, 10) + " --db " + db);
    INFO(revoke.out);
    REQUIRE(revoke.status == 0);
    REQUIRE(revoke.out.find("revoked") != std::string::npos);
    // The running server refuses the key from the next request on; the other keys still work.
    require_error(rc.Get("/api/v1/runs"), 401, "unauthorized", "revoked");
    REQUIRE(ts.client(ts.write_key).Get("/api/v1/runs")->status == 200);
    REQUIRE(key_with_prefix(cutload::server::list_api_keys(db), ts.read_key).revoked_at);

    // Revoking it again changes nothing and says so without failing.
    CliResult again = run_cli("keys revoke " + ts.read_key + " --db " + db);
    INFO(again.out);
    REQUIRE(again.status == 0);
    REQUIRE(again.out.find("already revoked") != std::string::npos);
}

TEST_CASE("keys: revoke refuses an unknown or too short or ambiguous prefix and list refuses a missing database") {
    TempDir dir;
    const std::string db = store_location(dir.path(), "k.db");
    cutload::server::create_api_key(db, cutload::server::Role::Admin, "a");
    // Two keys whose stored prefixes share their first characters.
    Sql(db).exec("INSERT INTO api_keys(hash, prefix, role, name, created_at) VALUES "
                 "('h1', 'clk_abc123', 'read', 'one', '2024-01-01T00:00:00.000Z'), "
                 "('h2', 'clk_abc456', 'read', 'two', '2024-01-01T00:00:00.000Z')");
    CliResult ambiguous = run_cli("keys revoke clk_abc --db " + db);
    REQUIRE(ambiguous.status != 0);
    REQUIRE(ambiguous.out.find("matches 2 keys") != std::string::npos);
    CliResult unknown = run_cli("keys revoke clk_ffffff --db " + db);
    REQUIRE(unknown.status != 0);
    REQUIRE(unknown.out.find("no API key with prefix 'clk_ffffff'") != std::string::npos);
    CliResult short_prefix = run_cli("keys revoke clk --db " + db);
    REQUIRE(short_prefix.status != 0);
    REQUIRE(short_prefix.out.find("too short") != std::string::npos);
    for (const auto& k : cutload::server::list_api_keys(db)) REQUIRE_FALSE(k.revoked_at);

    CliResult one = run_cli("keys revoke clk_abc4 --db " + db);
    INFO(one.out);
    REQUIRE(one.status == 0);
    for (const auto& k : cutload::server::list_api_keys(db)) REQUIRE(k.revoked_at.has_value() == (k.name == "two"));

    // SQLite: no file; PostgreSQL: an empty database (one without cutload's tables).
    const std::string nope = store_location(dir.path(), "nope.db");
    CliResult missing = run_cli("keys list --db " + nope);
    INFO(missing.out);
    REQUIRE(missing.status != 0);
    REQUIRE(missing.out.find("no database at") != std::string::npos);
    if (on_postgres())
        REQUIRE(Sql(nope).text("SELECT count(*) FROM pg_tables WHERE schemaname = 'public'") == "0");
    else
        REQUIRE_FALSE(fs::exists(dir.path() / "nope.db"));
}

TEST_CASE("keys: a schema 1 database upgrades in place and keeps its keys") {
    TempDir dir;
    const std::string db = store_location(dir.path(), "old.db");
    const std::string key = cutload::server::create_api_key(db, cutload::server::Role::Write, "old");
    // The schema version: SQLite keeps it in PRAGMA user_version, PostgreSQL in a table (db/postgres/schema.cpp).
    const std::string set_version_1 = on_postgres() ? "UPDATE cutload_schema SET version = 1" : "PRAGMA user_version=1";
    const std::string get_version = on_postgres() ? "SELECT version FROM cutload_schema" : "PRAGMA user_version";
    // Back to schema 1: api_keys without last_used_at (v2), no program tables (v3), no live tables
    // (v4), runs without leases (v5; optimizations go with v3).
    Sql(db).exec("ALTER TABLE api_keys DROP COLUMN last_used_at; DROP TABLE run_program; "
                 "DROP TABLE optimizations; DROP TABLE live_blocks; DROP TABLE live_chunks; DROP TABLE live_runs; "
                 "ALTER TABLE runs DROP COLUMN claim_token; ALTER TABLE runs DROP COLUMN lease_until; " +
                 set_version_1);
    const auto keys = cutload::server::list_api_keys(db);
    REQUIRE(keys.size() == 1);
    REQUIRE(keys[0].prefix == key.substr(0, 10));
    REQUIRE_FALSE(keys[0].last_used_at);
    const auto version = std::stoll(Sql(db).text(get_version));
    REQUIRE(version == cutload::db::schema_version());
}
