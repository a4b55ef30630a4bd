// Internal to server: API keys. A key is "clk_" + 48 random hex digits; the store keeps only its
// SHA-256, which is enough for keys of this entropy (no dictionary to attack).
#pragma once

#include "common.hpp"

namespace cutload::server {

std::string insert_api_key(db::Session& s, Role role, const std::string& name);

struct KeyMatch {
    Role role = Role::Read;
    std::string prefix;
    std::optional<std::string> revoked_at;
    bool last_use_stale = false;   // last_used_at unset or over a minute old
};
// The key with this SHA-256, revoked or not; nullopt when unknown.
std::optional<KeyMatch> lookup_api_key(db::Session& s, const std::string& key);
// Records a use of the key now. Best effort: skipped when another writer holds the store.
void touch_api_key(db::Session& s, const std::string& key);

}  // namespace cutload::server
