#include "server/auth.hpp"

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

std::optional<Role> lookup_api_key(db::Connection& c, const std::string& key) {
    auto st = c.prepare("SELECT role FROM api_keys WHERE hash = ? AND revoked_at IS NULL");
    st.bind(1, sha256_hex(key));
    if (!st.step()) return std::nullopt;
    return parse_role(st.text(0));
}

std::string create_api_key(const std::string& db_path, Role role, const std::string& name) {
    db::Connection c(db_path);
    db::migrate(c);
    return insert_api_key(c, role, name);
}

}  // namespace cutload::server
