// Internal to server: the error type every handler throws, small helpers.
#pragma once

#include "db/store.hpp"
#include "server/server.hpp"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>

namespace cutload::server {

using nlohmann::json;

// A rejected request: becomes {"error": {"code": code, "message": what()}} with this status.
class ApiError : public std::runtime_error {
public:
    ApiError(int status, std::string code, const std::string& message)
        : std::runtime_error(message), status(status), code(std::move(code)) {}
    int status;
    std::string code;
};

[[noreturn]] inline void not_found(const std::string& what) { throw ApiError(404, "not_found", what); }
[[noreturn]] inline void bad_request(const std::string& what) { throw ApiError(400, "bad_request", what); }

inline json error_body(const std::string& code, const std::string& message) {
    return json{{"error", {{"code", code}, {"message", message}}}};
}

// Parses a JSON request body or throws 400 naming the position of the syntax error.
json parse_json_body(const std::string& body, const char* what = "request body");

// Stored JSON text as a value; null when there is none.
inline json stored_json(const std::optional<std::string>& text) { return text ? json::parse(*text) : json(nullptr); }
template <class T>
json or_null(const std::optional<T>& v) {
    return v ? json(*v) : json(nullptr);
}

// Wall clock in seconds since the epoch (webhook scheduling).
double unix_now_s();

// Hex SHA-256 and HMAC-SHA-256 (OpenSSL's libcrypto).
std::string sha256_hex(const std::string& data);
std::string hmac_sha256_hex(const std::string& key, const std::string& data);

}  // namespace cutload::server
