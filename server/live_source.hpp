// Internal to server: a live source as requests and the machine library give it.
#pragma once

#include "common.hpp"

#include <string>

namespace cutload::server {

// The source's address ("shdr://HOST:PORT" or "http://HOST:PORT/PREFIX/DEVICE") from an address
// string, {"adapter": "HOST:PORT"} or {"agent": "http://HOST:PORT/PREFIX", "device": "NAME"}.
// ApiError 400 naming `key` (e.g. "source", "live_source") when it is none of these.
std::string live_source_address(const json& src, const std::string& key);

}  // namespace cutload::server
