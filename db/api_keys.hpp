// Public interface of db: API keys, by the SHA-256 of the key (the key itself is never stored).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace cutload::db {

struct ApiKeyRecord {
    std::int64_t id = 0;
    std::string prefix;   // the key's first characters, to tell keys apart in listings
    std::string role;     // read, write, admin
    std::optional<std::string> name;
    std::string created_at;
    std::optional<std::string> last_used_at, revoked_at;
};

class ApiKeyRepository {
public:
    virtual ~ApiKeyRepository() = default;
    virtual void create(const std::string& hash, const std::string& prefix, const std::string& role,
                        const std::optional<std::string>& name, const std::string& now) = 0;
    virtual std::optional<ApiKeyRecord> find_by_hash(const std::string& hash) = 0;
    // Records a use now. Best effort and never waits for another writer: false when the store
    // was busy (a later use records it).
    virtual bool touch(const std::string& hash, const std::string& now) = 0;
    virtual std::vector<ApiKeyRecord> list() = 0;   // oldest first
    // Keys whose hash is `hash`, or whose prefix starts with `text` or is the start of `text`.
    virtual std::vector<ApiKeyRecord> matching(const std::string& hash, const std::string& text) = 0;
    virtual void revoke(std::int64_t id, const std::string& at) = 0;
};

}  // namespace cutload::db
