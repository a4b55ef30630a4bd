// Internal to server: the machine, tool and material libraries that run specs may reference.
#pragma once

#include "common.hpp"
#include "db/library.hpp"

namespace cutload::server {

// The stored body of a library item with its name, or nullopt when the id does not exist.
std::optional<json> library_body(db::Session& s, db::LibraryKind kind, std::int64_t id);

// A complete, valid run spec used to validate one part (tool, material, limits) in isolation, so
// the engine's own error message names the key.
json probe_spec();

}  // namespace cutload::server
