// Internal to server: JSON a client sent (a body, a multipart part), parsed so that every refusal
// is a 400 that names the part, the byte and the key: a syntax error, and a number JSON can write
// but a double cannot hold (1e400), which the JSON library would otherwise throw as out_of_range.
#pragma once

#include "common.hpp"

#include <string>

namespace cutload::server {

// Parses `text`, sent as `what` ("request body", "part spec"); throws ApiError(400, code) naming
// what, the byte offset and the key path ("tool.diameter_mm", "tests[2].feed_mm_min").
json parse_client_json(const std::string& text, const std::string& what, const std::string& code = "bad_json");

}  // namespace cutload::server
