// Internal to server: the error type every handler throws, the connection pool, small helpers.
#pragma once

#include "db/db.hpp"
#include "server/server.hpp"

#include <nlohmann/json.hpp>

#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

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

// A JSON body as text. Every string the service puts into one is valid UTF-8 (client text goes
// through client_text(), logs and records through textio's readers); should one slip through, it
// is replaced with U+FFFD here rather than failing the answer with an exception.
inline std::string body_text(const json& body) { return body.dump(-1, ' ', false, json::error_handler_t::replace); }

// Text a client sent (a form part, an uploaded file's name) as UTF-8, decoded by textio's rules
// (valid UTF-8 as is, else Windows-1252 / Latin-1); a byte that is not text is a 400 naming `what`.
std::string client_text(const std::string& bytes, const std::string& what);

// SQLite connections, one per concurrent user; a connection is never used by two threads at once.
class DbPool {
public:
    explicit DbPool(std::string path) : path_(std::move(path)) {}

    class Lease {
    public:
        Lease(DbPool& pool, std::unique_ptr<db::Connection> c) : pool_(&pool), c_(std::move(c)) {}
        Lease(Lease&&) = default;
        ~Lease() {
            if (c_) pool_->give_back(std::move(c_));
        }
        db::Connection& operator*() { return *c_; }
        db::Connection* operator->() { return c_.get(); }

    private:
        DbPool* pool_;
        std::unique_ptr<db::Connection> c_;
    };

    Lease get() {
        {
            std::lock_guard lk(mu_);
            if (!idle_.empty()) {
                auto c = std::move(idle_.back());
                idle_.pop_back();
                return Lease(*this, std::move(c));
            }
        }
        return Lease(*this, std::make_unique<db::Connection>(path_));
    }

private:
    void give_back(std::unique_ptr<db::Connection> c) {
        std::lock_guard lk(mu_);
        idle_.push_back(std::move(c));
    }
    std::string path_;
    std::mutex mu_;
    std::vector<std::unique_ptr<db::Connection>> idle_;
};

// Parses a JSON request body or throws 400 naming the position of the syntax error.
json parse_json_body(const std::string& body, const char* what = "request body");

// Reads the JSON text of a column.
inline json column_json(const db::Stmt& st, int col) {
    return st.is_null(col) ? json(nullptr) : json::parse(st.text(col));
}

// Wall clock in seconds since the epoch (webhook scheduling).
double unix_now_s();

// Hex SHA-256 and HMAC-SHA-256 (OpenSSL's libcrypto).
std::string sha256_hex(const std::string& data);
std::string hmac_sha256_hex(const std::string& key, const std::string& data);

}  // namespace cutload::server
