// Internal to server: the machine, tool and material libraries that run specs may reference.
#pragma once

#include "common.hpp"
#include "db/library.hpp"

namespace cutload::server {

// The stored body of a library item with its name, or nullopt when the id does not exist.
std::optional<json> library_body(db::Session& s, db::LibraryKind kind, std::int64_t id);

}  // namespace cutload::server
