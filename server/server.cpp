#include "server/server.hpp"

#include "app/inputs.hpp"
#include "auth.hpp"
#include "core.hpp"
#include "gzip.hpp"
#include "jobs.hpp"
#include "webhooks.hpp"

#include "textio/text.hpp"

#include <fcntl.h>
#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <sys/file.h>
#include <unistd.h>

#include <chrono>
#include <regex>

namespace cutload::server {
namespace fs = std::filesystem;

namespace {

const char* status_code_name(int status) {
    switch (status) {
        case 400: return "bad_request";
        case 401: return "unauthorized";
        case 403: return "forbidden";
        case 404: return "not_found";
        case 405: return "method_not_allowed";
        case 409: return "conflict";
        case 413: return "payload_too_large";
        case 414: return "uri_too_long";
        case 429: return "too_many_requests";
        default: return status >= 500 ? "internal" : "bad_request";
    }
}

bool is_loopback(const std::string& addr) {
    return addr == "::1" || addr.rfind("127.", 0) == 0 || addr.rfind("::ffff:127.", 0) == 0;
}

fs::path default_data_dir(const ServerOptions& o) {
    if (!o.data_dir.empty()) return o.data_dir;
    return fs::path(o.db_path + ".data");
}

// Uploads that never got their run row (crash between the file write and the commit).
void remove_orphan_uploads(db::Connection& c, const fs::path& data_dir) {
    std::error_code ec;
    fs::remove_all(data_dir / "tmp", ec);
    fs::create_directories(data_dir / "tmp");
    fs::create_directories(data_dir / "uploads");
    auto st = c.prepare("SELECT 1 FROM runs WHERE upload_dir = ?");
    for (const auto& e : fs::directory_iterator(data_dir / "uploads")) {
        const std::string rel = "uploads/" + e.path().filename().string();
        st.reset();
        st.bind(1, rel);
        if (!st.step()) {
            spdlog::warn("removing orphan upload {}", (data_dir / rel).string());
            fs::remove_all(e.path(), ec);
        }
    }
}

}  // namespace

std::int64_t Ctx::id(std::size_t n) const {
    try {
        return std::stoll(req.matches[n].str());
    } catch (const std::exception&) {
        bad_request(fmt::format("path parameter '{}' is not a valid id", req.matches[n].str()));
    }
}

bool Ctx::wants_csv() const {
    const std::string accept = req.get_header_value("Accept");
    return accept.find("text/csv") != std::string::npos || param("format").value_or("") == "csv";
}

void Ctx::reply(int status, const json& body) {
    res.status = status;
    res.set_content(body_text(body), "application/json");
}

std::string client_text(const std::string& bytes, const std::string& what) {
    if (textio::is_ascii(bytes) && bytes.find('\0') == std::string::npos) return bytes;
    std::string out;
    if (const auto r = textio::append_utf8(out, bytes))
        bad_request(fmt::format("{}: character {}: {}", what, r->column, r->why()));
    return out;
}

std::optional<std::string> Ctx::param(const char* name) const {
    if (!req.has_param(name)) return std::nullopt;
    return req.get_param_value(name);
}

std::optional<double> Ctx::param_double(const char* name) const {
    auto s = param(name);
    if (!s) return std::nullopt;
    try {
        std::size_t used = 0;
        double v = std::stod(*s, &used);
        if (used == s->size() && std::isfinite(v)) return v;
    } catch (const std::exception&) {
    }
    bad_request(fmt::format("query parameter {}: '{}' is not a number", name, *s));
}

std::optional<std::int64_t> Ctx::param_int(const char* name) const {
    auto s = param(name);
    if (!s) return std::nullopt;
    try {
        std::size_t used = 0;
        long long v = std::stoll(*s, &used);
        if (used == s->size()) return v;
    } catch (const std::exception&) {
    }
    bad_request(fmt::format("query parameter {}: '{}' is not an integer", name, *s));
}

std::optional<bool> Ctx::param_bool(const char* name) const {
    auto s = param(name);
    if (!s) return std::nullopt;
    if (*s == "true" || *s == "1") return true;
    if (*s == "false" || *s == "0") return false;
    bad_request(fmt::format("query parameter {}: '{}' is not true or false", name, *s));
}

Core::Core(ServerOptions o)
    : opt(std::move(o)), data_dir(default_data_dir(opt)), pool(opt.db_path), series_cache(opt.cache_bytes) {}

Core::~Core() {
    if (lock_fd >= 0) ::close(lock_fd);
}

Role Core::authorize(const httplib::Request& req, Role need, std::string* actor) {
    const std::string auth = req.get_header_value("Authorization");
    *actor = "anonymous";
    if (auth.empty()) {
        if (need == Role::Read && opt.anonymous_loopback_reads && is_loopback(req.remote_addr)) return Role::Read;
        throw ApiError(401, "unauthorized", "missing API key: send 'Authorization: Bearer <key>'");
    }
    if (auth.rfind("Bearer ", 0) != 0)
        throw ApiError(401, "unauthorized", "Authorization header must be 'Bearer <key>'");
    const std::string key = auth.substr(7);
    auto c = pool.get();
    auto found = lookup_api_key(*c, key);
    if (!found) throw ApiError(401, "unauthorized", "unknown API key");
    if (found->revoked_at)
        throw ApiError(401, "unauthorized", fmt::format("API key {} was revoked at {}", found->prefix, *found->revoked_at));
    if (found->last_use_stale) touch_api_key(*c, key);
    *actor = found->prefix;
    if (static_cast<int>(found->role) < static_cast<int>(need))
        throw ApiError(403, "forbidden", fmt::format("this request needs the {} role; the key has {}", role_name(need),
                                                     role_name(found->role)));
    return found->role;
}

void Core::route(const std::string& method, const std::string& path, std::optional<Role> need, Handler h) {
    route_list.emplace_back(method, path);
    const std::string pattern = std::regex_replace(path, std::regex(R"(\{[a-z_]+\})"), "([0-9]+)");
    auto wrapped = [this, method, path, need, h](const httplib::Request& req, httplib::Response& res) {
        const auto t0 = std::chrono::steady_clock::now();
        try {
            std::string actor = "anonymous";
            const Role role = need ? authorize(req, *need, &actor) : Role::Read;
            Ctx ctx{req, res, role, actor};
            h(ctx);
        } catch (const ApiError& e) {
            res.status = e.status;
            res.set_content(body_text(error_body(e.code, e.what())), "application/json");
        } catch (const force_model::SpecError& e) {
            res.status = 400;
            res.set_content(body_text(error_body("bad_spec", e.what())), "application/json");
        } catch (const motion_io::IngestError& e) {
            res.status = 400;
            res.set_content(body_text(error_body("bad_log", e.what())), "application/json");
        } catch (const app::InputError& e) {
            res.status = 400;
            res.set_content(body_text(error_body("bad_request", e.what())), "application/json");
        } catch (const db::Error& e) {
            const bool conflict = e.is_constraint();
            res.status = conflict ? 409 : 500;
            if (!conflict) spdlog::error("{} {}: {}", method, req.path, e.what());
            res.set_content(body_text(error_body(conflict ? "conflict" : "internal", conflict ? e.what() : "database error")),
                            "application/json");
        } catch (const std::exception& e) {
            spdlog::error("{} {}: {}", method, req.path, textio::printable(e.what()));
            res.status = 500;
            res.set_content(body_text(error_body("internal", e.what())), "application/json");
        }
        compress_answer(req, res);
        metrics.request(method, path, res.status,
                        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    };
    if (method == "GET")
        http.Get(pattern, wrapped);
    else if (method == "POST")
        http.Post(pattern, wrapped);
    else if (method == "PUT")
        http.Put(pattern, wrapped);
    else if (method == "DELETE")
        http.Delete(pattern, wrapped);
    else
        throw std::logic_error("unsupported method " + method);
}

struct Server::Impl : Core {
    using Core::Core;
    std::thread listener;
    std::mutex mu;
    std::condition_variable cv;
    bool stopped = false, finished = false, started = false;
    int bound_port = 0;
};

Server::Server(ServerOptions opt) : impl_(std::make_unique<Impl>(std::move(opt))) {
    auto& c = *impl_;
    // One server per database: the job queue assumes no other process claims runs.
    c.lock_fd = ::open((c.opt.db_path + ".lock").c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (c.lock_fd < 0 || ::flock(c.lock_fd, LOCK_EX | LOCK_NB) != 0)
        throw std::runtime_error(fmt::format("{} is in use by another cutload serve (lock {}.lock)", c.opt.db_path,
                                             c.opt.db_path));
    {
        auto conn = c.pool.get();
        db::migrate(*conn);
        fs::create_directories(c.data_dir);
        remove_orphan_uploads(*conn, c.data_dir);
    }
    c.hooks = std::make_unique<Webhooks>(c.pool, c.opt, c.metrics);
    c.jobs = std::make_unique<Jobs>(c.pool, c.opt, c.data_dir, c.metrics, [&c] { c.hooks->notify(); });

    const int threads = std::max(4, c.opt.http_threads);
    c.http.new_task_queue = [threads] { return new httplib::ThreadPool(static_cast<std::size_t>(threads)); };
    c.http.set_payload_max_length(c.opt.max_body_bytes);
    c.http.set_keep_alive_max_count(100000);
    // Without it, Nagle's algorithm and delayed ACKs hold small responses for ~40 ms.
    c.http.set_tcp_nodelay(true);
    // Debian's httplib compresses with brotli at its slowest setting whenever a client offers "br"
    // (measured: 1.7-2.0 s for a 627 KB forces window, against 0.05 s with gzip), and every
    // browser offers it. Drop "br" from the offer before routing so large answers go out gzipped.
    // The request object is httplib's own mutable local; only the handler signature is const.
    c.http.set_pre_routing_handler([](const httplib::Request& req, httplib::Response&) {
        auto it = req.headers.find("Accept-Encoding");
        if (it != req.headers.end() && it->second.find("br") != std::string::npos) {
            auto& headers = const_cast<httplib::Headers&>(req.headers);
            const bool gzip = it->second.find("gzip") != std::string::npos;
            headers.erase("Accept-Encoding");
            if (gzip) headers.emplace("Accept-Encoding", "gzip");
        }
        return httplib::Server::HandlerResponse::Unhandled;
    });
    c.http.set_error_handler([&c](const httplib::Request& req, httplib::Response& res) {
        if (!res.body.empty()) return;
        // httplib refuses a POST/PUT without Content-Length before any handler sees it.
        const bool no_length = res.status == 400 && (req.method == "POST" || req.method == "PUT") &&
                               !req.has_header("Content-Length") && !req.has_header("Transfer-Encoding");
        std::string msg = res.status == 404 ? fmt::format("no such resource: {} {}", req.method, req.path)
                        : res.status == 413 ? fmt::format("request body exceeds the limit of {} bytes", c.opt.max_body_bytes)
                        : no_length ? fmt::format("{} {}: send a body or Content-Length: 0 (curl: -d '' or -d '{{}}')", req.method, req.path)
                                    : fmt::format("HTTP {}", res.status);
        res.set_content(body_text(error_body(status_code_name(res.status), msg)), "application/json");
        c.metrics.request(req.method, "unmatched", res.status, 0);
    });
    if (!c.opt.web_dir.empty() && fs::is_directory(c.opt.web_dir)) c.http.set_mount_point("/", c.opt.web_dir);

    add_library_routes(c);
    add_run_routes(c);
    add_program_routes(c);
    add_measurement_routes(c);
    add_calibration_routes(c);
    add_alert_routes(c);
    add_misc_routes(c);
    add_view_routes(c);
}

Server::~Server() { stop(); }

void Server::start() {
    auto& c = *impl_;
    c.bound_port = c.opt.port == 0 ? c.http.bind_to_any_port(c.opt.host) : (c.http.bind_to_port(c.opt.host, c.opt.port) ? c.opt.port : -1);
    if (c.bound_port < 0) throw std::runtime_error(fmt::format("cannot listen on {}:{}", c.opt.host, c.opt.port));
    c.jobs->start();
    c.hooks->start();
    c.listener = std::thread([&c] { c.http.listen_after_bind(); });
    c.started = true;
    spdlog::info("cutload serve: listening on http://{}:{} (db {}, {} worker(s))", c.opt.host, c.bound_port,
                 c.opt.db_path, c.opt.workers);
}

void Server::stop() {
    auto& c = *impl_;
    {
        std::lock_guard lk(c.mu);
        if (c.stopped) return;
        c.stopped = true;
    }
    if (c.started) {
        c.http.stop();
        if (c.listener.joinable()) c.listener.join();
    }
    c.jobs->stop(c.opt.drain_s);
    c.hooks->stop();
    {
        std::lock_guard lk(c.mu);
        c.finished = true;
    }
    c.cv.notify_all();
}

void Server::wait() {
    auto& c = *impl_;
    std::unique_lock lk(c.mu);
    c.cv.wait(lk, [&c] { return c.finished; });
}

int Server::port() const { return impl_->bound_port; }

std::vector<std::pair<std::string, std::string>> Server::routes() const { return impl_->route_list; }

}  // namespace cutload::server
