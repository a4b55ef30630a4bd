#include "auth.hpp"
#include "json_in.hpp"

#include "db/api_keys.hpp"

#include <fmt/format.h>
#include <openssl/evp.h>
#include <openssl/hmac.h>
#include <openssl/rand.h>

#include <chrono>
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

json parse_json_body(const std::string& body, const char* what) { return parse_client_json(body, what, "bad_json"); }

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

std::string insert_api_key(db::Session& s, Role role, const std::string& name) {
    unsigned char raw[24];
    if (RAND_bytes(raw, sizeof raw) != 1) throw std::runtime_error("no randomness for a new API key (libcrypto)");
    std::string key = "clk_" + to_hex(raw, sizeof raw);
    s.api_keys().create(sha256_hex(key), key.substr(0, 10), role_name(role),
                        name.empty() ? std::nullopt : std::optional<std::string>(name), db::now_iso());
    return key;
}

std::optional<KeyMatch> lookup_api_key(db::Session& s, const std::string& key) {
    const auto k = s.api_keys().find_by_hash(sha256_hex(key));
    if (!k) return std::nullopt;
    // Stored times are ISO text, which sorts as the times do.
    const std::string a_minute_ago = db::iso_time(std::chrono::system_clock::now() - std::chrono::seconds(60));
    return KeyMatch{parse_role(k->role), k->prefix, k->revoked_at, !k->last_used_at || *k->last_used_at < a_minute_ago};
}

void touch_api_key(db::Session& s, const std::string& key) {
    // A read request never waits for this behind a job's long result transaction: when the store
    // is busy a later request records the use.
    s.api_keys().touch(sha256_hex(key), db::now_iso());
}

namespace {

ApiKeyInfo key_info(const db::ApiKeyRecord& k) {
    return ApiKeyInfo{k.prefix, parse_role(k.role), k.name.value_or(""), k.created_at, k.last_used_at, k.revoked_at};
}

// Listing or revoking must not create a database because of a typo in its path.
std::unique_ptr<db::Store> existing_store(const std::string& db_path) {
    auto store = db::Store::open(db_path, db::Store::Open::MustExist);
    store->migrate();
    return store;
}

}  // namespace

std::vector<ApiKeyInfo> list_api_keys(const std::string& db_path) {
    auto store = existing_store(db_path);
    std::vector<ApiKeyInfo> out;
    for (const auto& k : store->session()->api_keys().list()) out.push_back(key_info(k));
    return out;
}

ApiKeyInfo revoke_api_key(const std::string& db_path, const std::string& prefix_or_key, bool* already_revoked) {
    if (prefix_or_key.size() < 6)
        throw std::invalid_argument(fmt::format("key prefix '{}' is too short: give the prefix `cutload keys list` shows",
                                                prefix_or_key));
    auto store = existing_store(db_path);
    auto s = store->session();
    db::Transaction tx(*s);
    // A whole key matches by its hash; anything shorter by the stored prefix.
    const auto found = s->api_keys().matching(sha256_hex(prefix_or_key), prefix_or_key);
    if (found.empty()) throw std::invalid_argument(fmt::format("no API key with prefix '{}' in {}", prefix_or_key, db::printable_location(db_path)));
    if (found.size() > 1) {
        std::string which;
        for (const auto& k : found) which += (which.empty() ? "" : ", ") + k.prefix + " (" + k.name.value_or("") + ")";
        throw std::invalid_argument(
            fmt::format("prefix '{}' matches {} keys: {}; give the whole key to revoke one", prefix_or_key,
                        found.size(), which));
    }
    ApiKeyInfo k = key_info(found[0]);
    if (already_revoked) *already_revoked = k.revoked_at.has_value();
    if (!k.revoked_at) {
        k.revoked_at = db::now_iso();
        s->api_keys().revoke(found[0].id, *k.revoked_at);
    }
    tx.commit();
    return k;
}

std::string printable_db(const std::string& db_path) { return db::printable_location(db_path); }

std::string create_api_key(const std::string& db_path, Role role, const std::string& name) {
    auto store = db::Store::open(db_path);
    store->migrate();
    return insert_api_key(*store->session(), role, name);
}

}  // namespace cutload::server
