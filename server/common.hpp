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

// The error answer. The message may carry bytes from an exception's text (a client's file name, a
// line of a log): a byte that is not UTF-8 is decoded as textio does or written as \xNN, never thrown.
json error_body(const std::string& code, const std::string& message);

// A JSON body as text. Every string the service puts into one is valid UTF-8 (client text goes
// through client_text(), logs and records through textio's readers); should one slip through, it
// is replaced with U+FFFD here rather than failing the answer with an exception.
inline std::string body_text(const json& body) { return body.dump(-1, ' ', false, json::error_handler_t::replace); }

// Text a client sent (a form part, an uploaded file's name) as UTF-8, decoded by textio's rules
// (valid UTF-8 as is, else Windows-1252 / Latin-1); a byte that is not text is a 400 naming `what`.
std::string client_text(const std::string& bytes, const std::string& what);

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
