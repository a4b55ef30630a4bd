// PostgreSQL: API keys.
#include "postgres/store.hpp"

namespace cutload::db::postgres {
namespace {

constexpr const char* kSelect = "SELECT id, prefix, role, name, created_at, last_used_at, revoked_at FROM api_keys ";

ApiKeyRecord key_row(const Result& r, int i) {
    return ApiKeyRecord{r.i64(i, 0),       r.text(i, 1),      r.text(i, 2),     r.opt_text(i, 3),
                        r.text(i, 4),      r.opt_text(i, 5),  r.opt_text(i, 6)};
}

std::vector<ApiKeyRecord> keys_of(const Result& r) {
    std::vector<ApiKeyRecord> out;
    for (int i = 0; i < r.rows(); ++i) out.push_back(key_row(r, i));
    return out;
}

}  // namespace

void ApiKeys::create(const std::string& hash, const std::string& prefix, const std::string& role,
                     const std::optional<std::string>& name, const std::string& now) {
    c_.run("INSERT INTO api_keys(hash, prefix, role, name, created_at) VALUES ($1,$2,$3,$4,$5)",
           Params().add(hash).add(prefix).add(role).add(name).add(now));
}

std::optional<ApiKeyRecord> ApiKeys::find_by_hash(const std::string& hash) {
    auto r = c_.run(std::string(kSelect) + "WHERE hash = $1", Params().add(hash));
    if (r.empty()) return std::nullopt;
    return key_row(r, 0);
}

bool ApiKeys::touch(const std::string& hash, const std::string& now) {
    // Never waits: a key row another transaction holds (revoking it, touching it) is skipped,
    // and a later use records the time.
    try {
        return guarded(c_, [&] {
            return c_.run("UPDATE api_keys SET last_used_at = $1 WHERE id = "
                          "(SELECT id FROM api_keys WHERE hash = $2 FOR UPDATE SKIP LOCKED)",
                          Params().add(now).add(hash))
                       .affected() > 0;
        });
    } catch (const Error&) {
        return false;
    }
}

std::vector<ApiKeyRecord> ApiKeys::list() { return keys_of(c_.run(std::string(kSelect) + "ORDER BY id")); }

std::vector<ApiKeyRecord> ApiKeys::matching(const std::string& hash, const std::string& text) {
    return keys_of(c_.run(std::string(kSelect) +
                              "WHERE hash = $1 OR substr(prefix, 1, length($2)) = $2 OR substr($2, 1, length(prefix)) = prefix "
                              "ORDER BY id",
                          Params().add(hash).add(text)));
}

void ApiKeys::revoke(std::int64_t id, const std::string& at) {
    c_.run("UPDATE api_keys SET revoked_at = $1 WHERE id = $2", Params().add(at).add(id));
}

}  // namespace cutload::db::postgres
