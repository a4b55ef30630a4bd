// SQLite: API keys.
#include "sqlite/store.hpp"

namespace cutload::db::sqlite {
namespace {

constexpr const char* kSelect = "SELECT id, prefix, role, name, created_at, last_used_at, revoked_at FROM api_keys ";

ApiKeyRecord key_row(const Stmt& st) {
    return ApiKeyRecord{st.i64(0), st.text(1), st.text(2), st.opt_text(3), st.text(4), st.opt_text(5), st.opt_text(6)};
}

}  // namespace

void ApiKeys::create(const std::string& hash, const std::string& prefix, const std::string& role,
                     const std::optional<std::string>& name, const std::string& now) {
    c_.prepare("INSERT INTO api_keys(hash, prefix, role, name, created_at) VALUES (?,?,?,?,?)")
        .bind(1, hash)
        .bind(2, prefix)
        .bind(3, role)
        .bind(4, name)
        .bind(5, now)
        .run();
}

std::optional<ApiKeyRecord> ApiKeys::find_by_hash(const std::string& hash) {
    auto st = c_.prepare(std::string(kSelect) + "WHERE hash = ?");
    st.bind(1, hash);
    if (!st.step()) return std::nullopt;
    return key_row(st);
}

bool ApiKeys::touch(const std::string& hash, const std::string& now) {
    // A read request must never wait behind a job's long result transaction for this.
    c_.set_busy_timeout(0);
    bool done = true;
    try {
        c_.prepare("UPDATE api_keys SET last_used_at = ? WHERE hash = ?").bind(1, now).bind(2, hash).run();
    } catch (const Error&) {
        done = false;
    }
    c_.set_busy_timeout(kBusyTimeoutMs);
    return done;
}

std::vector<ApiKeyRecord> ApiKeys::list() {
    auto st = c_.prepare(std::string(kSelect) + "ORDER BY id");
    std::vector<ApiKeyRecord> out;
    while (st.step()) out.push_back(key_row(st));
    return out;
}

std::vector<ApiKeyRecord> ApiKeys::matching(const std::string& hash, const std::string& text) {
    auto st = c_.prepare(std::string(kSelect) +
                         "WHERE hash = ?1 OR substr(prefix, 1, length(?2)) = ?2 OR substr(?2, 1, length(prefix)) = prefix "
                         "ORDER BY id");
    st.bind(1, hash).bind(2, text);
    std::vector<ApiKeyRecord> out;
    while (st.step()) out.push_back(key_row(st));
    return out;
}

void ApiKeys::revoke(std::int64_t id, const std::string& at) {
    c_.prepare("UPDATE api_keys SET revoked_at = ? WHERE id = ?").bind(1, at).bind(2, id).run();
}

}  // namespace cutload::db::sqlite
