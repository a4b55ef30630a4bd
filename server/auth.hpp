// Internal to server: API keys. A key is "clk_" + 48 random hex digits; the store keeps only its
// SHA-256, which is enough for keys of this entropy (no dictionary to attack).
#pragma once

#include "server/common.hpp"

namespace cutload::server {

std::string insert_api_key(db::Connection& c, Role role, const std::string& name);
std::optional<Role> lookup_api_key(db::Connection& c, const std::string& key);

}  // namespace cutload::server
