#include "auth.hpp"

#include <fmt/format.h>
#include <openssl/evp.h>
#include <openssl/hmac.h>
#include <openssl/rand.h>

#include <chrono>
#include <filesystem>
#include <stdexcept>

namespace cutload::server {
namespace {

std::string to_hex(const unsigned char* p, std::size_t n) {
    static const char* digits = "0123456789abcdef";
    std::string s(2 * n, '0');
    for (std::size_t i = 0; i < n; ++i) {
        s[2 * i] = digits[p[i] >> 4];
        s[2 * i + 1] = digits[p[i] & 15];
    }
    return s;
}

}  // namespace

std::string sha256_hex(const std::string& data) {
    unsigned char md[EVP_MAX_MD_SIZE];
    unsigned int n = 0;
    if (EVP_Digest(data.data(), data.size(), md, &n, EVP_sha256(), nullptr) != 1)
        throw std::runtime_error("SHA-256 failed (libcrypto)");
    return to_hex(md, n);
}

std::string hmac_sha256_hex(const std::string& key, const std::string& data) {
    unsigned char md[EVP_MAX_MD_SIZE];
    unsigned int n = 0;
    if (!HMAC(EVP_sha256(), key.data(), static_cast<int>(key.size()),
              reinterpret_cast<const unsigned char*>(data.data()), data.size(), md, &n))
        throw std::runtime_error("HMAC-SHA-256 failed (libcrypto)");
    return to_hex(md, n);
}

double unix_now_s() {
    using namespace std::chrono;
    return duration<double>(system_clock::now().time_since_epoch()).count();
}

json parse_json_body(const std::string& body, const char* what) {
    try {
        return json::parse(body);
    } catch (const json::parse_error& e) {
        throw ApiError(400, "bad_json", fmt::format("{} is not valid JSON: byte {}: {}", what, e.byte, e.what()));
    }
}

Role parse_role(const std::string& s) {
    if (s == "read") return Role::Read;
    if (s == "write") return Role::Write;
    if (s == "admin") return Role::Admin;
    throw std::invalid_argument(fmt::format("unknown role '{}': expected read, write or admin", s));
}

const char* role_name(Role r) {
    switch (r) {
        case Role::Read: return "read";
        case Role::Write: return "write";
        case Role::Admin: return "admin";
    }
    return "?";
}

std::string insert_api_key(db::Connection& c, Role role, const std::string& name) {
    unsigned char raw[24];
    if (RAND_bytes(raw, sizeof raw) != 1) throw std::runtime_error("no randomness for a new API key (libcrypto)");
    std::string key = "clk_" + to_hex(raw, sizeof raw);
    auto st = c.prepare("INSERT INTO api_keys(hash, prefix, role, name, created_at) VALUES (?,?,?,?,?)");
    st.bind(1, sha256_hex(key)).bind(2, key.substr(0, 10)).bind(3, role_name(role));
    if (name.empty())
        st.bind_null(4);
    else
        st.bind(4, name);
    st.bind(5, db::now_iso()).run();
    return key;
}

std::optional<KeyMatch> lookup_api_key(db::Connection& c, const std::string& key) {
    auto st = c.prepare(
        "SELECT role, prefix, revoked_at, last_used_at IS NULL OR "
        "last_used_at < strftime('%Y-%m-%dT%H:%M:%fZ', 'now', '-60 seconds') FROM api_keys WHERE hash = ?");
    st.bind(1, sha256_hex(key));
    if (!st.step()) return std::nullopt;
    return KeyMatch{parse_role(st.text(0)), st.text(1), st.opt_text(2), st.i64(3) != 0};
}

void touch_api_key(db::Connection& c, const std::string& key) {
    // A read request must never wait behind a job's long result transaction for this.
    c.set_busy_timeout(0);
    try {
        c.prepare("UPDATE api_keys SET last_used_at = ? WHERE hash = ?").bind(1, db::now_iso()).bind(2, sha256_hex(key)).run();
    } catch (const db::Error&) {
        // Busy: a later request records the use.
    }
    c.set_busy_timeout(db::kBusyTimeoutMs);
}

namespace {

ApiKeyInfo key_info(const db::Stmt& st) {
    return ApiKeyInfo{st.text(0), parse_role(st.text(1)), st.opt_text(2).value_or(""), st.text(3), st.opt_text(4),
                      st.opt_text(5)};
}

constexpr const char* kKeyColumns = "prefix, role, name, created_at, last_used_at, revoked_at";

// Listing or revoking must not create a database because of a typo in its path.
void require_database(const std::string& db_path) {
    if (!std::filesystem::exists(db_path)) throw std::invalid_argument(fmt::format("no database at {}", db_path));
}

}  // namespace

std::vector<ApiKeyInfo> list_api_keys(const std::string& db_path) {
    require_database(db_path);
    db::Connection c(db_path);
    db::migrate(c);
    auto st = c.prepare(fmt::format("SELECT {} FROM api_keys ORDER BY id", kKeyColumns));
    std::vector<ApiKeyInfo> out;
    while (st.step()) out.push_back(key_info(st));
    return out;
}

ApiKeyInfo revoke_api_key(const std::string& db_path, const std::string& prefix_or_key, bool* already_revoked) {
    if (prefix_or_key.size() < 6)
        throw std::invalid_argument(fmt::format("key prefix '{}' is too short: give the prefix `cutload keys list` shows",
                                                prefix_or_key));
    require_database(db_path);
    db::Connection c(db_path);
    db::migrate(c);
    db::Transaction tx(c);
    // A whole key matches by its hash; anything shorter by the stored prefix.
    auto st = c.prepare(fmt::format("SELECT {}, id FROM api_keys WHERE hash = ?1 OR substr(prefix, 1, length(?2)) = ?2 "
                                    "OR substr(?2, 1, length(prefix)) = prefix ORDER BY id",
                                    kKeyColumns));
    st.bind(1, sha256_hex(prefix_or_key)).bind(2, prefix_or_key);
    std::vector<std::pair<ApiKeyInfo, std::int64_t>> found;
    while (st.step()) found.emplace_back(key_info(st), st.i64(6));
    if (found.empty()) throw std::invalid_argument(fmt::format("no API key with prefix '{}' in {}", prefix_or_key, db_path));
    if (found.size() > 1) {
        std::string which;
        for (const auto& [k, id] : found) which += (which.empty() ? "" : ", ") + k.prefix + " (" + k.name + ")";
        throw std::invalid_argument(
            fmt::format("prefix '{}' matches {} keys: {}; give the whole key to revoke one", prefix_or_key,
                        found.size(), which));
    }
    ApiKeyInfo k = found[0].first;
    if (already_revoked) *already_revoked = k.revoked_at.has_value();
    if (!k.revoked_at) {
        k.revoked_at = db::now_iso();
        c.prepare("UPDATE api_keys SET revoked_at = ? WHERE id = ?").bind(1, *k.revoked_at).bind(2, found[0].second).run();
    }
    tx.commit();
    return k;
}

std::string create_api_key(const std::string& db_path, Role role, const std::string& name) {
    db::Connection c(db_path);
    db::migrate(c);
    return insert_api_key(c, role, name);
}

}  // namespace cutload::server
