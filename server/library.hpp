// Internal to server: the machine, tool and material libraries that run specs may reference.
#pragma once

#include "common.hpp"

namespace cutload::server {

// The stored body of a library item, or nullopt when the id does not exist.
// table: "machines", "tools" or "materials".
std::optional<json> library_body(db::Connection& c, const char* table, std::int64_t id);

}  // namespace cutload::server
