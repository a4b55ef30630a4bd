#include "server/server.hpp"

#include "app/inputs.hpp"
#include "auth.hpp"
#include "core.hpp"
#include "db/runs.hpp"
#include "gzip.hpp"
#include "http_guard.hpp"
#include "jobs.hpp"
#include "live_runs.hpp"
#include "webhooks.hpp"

#include "textio/text.hpp"

#include <fcntl.h>
#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <charconv>
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

fs::path default_data_dir(const ServerOptions& o) {
    if (!o.data_dir.empty()) return o.data_dir;
    // Uploads are files: beside an SQLite file by default; a PostgreSQL URL names no folder.
    if (db::backend_of(o.db_path) == db::Backend::Postgres)
        throw std::invalid_argument(fmt::format("{}: a PostgreSQL store needs --data-dir (the folder for uploaded logs)",
                                                db::printable_location(o.db_path)));
    return fs::path(o.db_path + ".data");
}

// How old an upload folder without its run must be before a server on a shared store removes it:
// another server may be between writing that folder and committing its run.
constexpr auto kSharedOrphanAge = std::chrono::hours(1);

// Uploads that never got their run row (crash between the file write and the commit). On a
// shared store (several servers, one --data-dir) only folders older than kSharedOrphanAge go,
// and tmp/ is left to the others' uploads in progress.
void remove_orphan_uploads(db::RunRepository& runs, const fs::path& data_dir, bool shared) {
    std::error_code ec;
    if (!shared) fs::remove_all(data_dir / "tmp", ec);
    fs::create_directories(data_dir / "tmp");
    fs::create_directories(data_dir / "uploads");
    const auto now = fs::file_time_type::clock::now();
    for (const auto& e : fs::directory_iterator(data_dir / "uploads")) {
        const std::string rel = "uploads/" + e.path().filename().string();
        if (shared && now - fs::last_write_time(e.path(), ec) < kSharedOrphanAge) continue;
        if (!runs.upload_dir_in_use(rel)) {
            spdlog::warn("removing orphan upload {}", (data_dir / rel).string());
            fs::remove_all(e.path(), ec);
        }
    }
}

}  // namespace

const ParamValue& Ctx::value_of(std::string_view name, ParamType type) const {
    for (std::size_t i = 0; i < route.params.size(); ++i)
        if (route.params[i].name == name) {
            if (route.params[i].type != type)
                throw std::logic_error(fmt::format("{} {}: parameter {} is read as another type than declared", route.method,
                                                   route.path, name));
            return values[i];
        }
    throw std::logic_error(fmt::format("{} {}: parameter {} is not declared", route.method, route.path, name));
}

std::int64_t Ctx::id() const { return std::get<std::int64_t>(value_of("id", ParamType::Integer)); }

std::optional<std::string> Ctx::param(std::string_view name) const {
    const auto& v = value_of(name, ParamType::String);
    if (const auto* s = std::get_if<std::string>(&v)) return *s;
    return std::nullopt;
}

std::optional<double> Ctx::param_double(std::string_view name) const {
    const auto& v = value_of(name, ParamType::Number);
    if (const auto* d = std::get_if<double>(&v)) return *d;
    return std::nullopt;
}

std::optional<std::int64_t> Ctx::param_int(std::string_view name) const {
    const auto& v = value_of(name, ParamType::Integer);
    if (const auto* i = std::get_if<std::int64_t>(&v)) return *i;
    return std::nullopt;
}

std::optional<bool> Ctx::param_bool(std::string_view name) const {
    const auto& v = value_of(name, ParamType::Boolean);
    if (const auto* b = std::get_if<bool>(&v)) return *b;
    return std::nullopt;
}

bool Ctx::given(std::string_view name) const {
    for (const Param& p : route.params)
        if (p.name == name) return p.in == ParamIn::Path || req.has_param(p.name);
    throw std::logic_error(fmt::format("{} {}: parameter {} is not declared", route.method, route.path, name));
}

bool Ctx::wants_csv() const {
    if (req.get_header_value("Accept").find("text/csv") != std::string::npos) return true;
    for (const Param& p : route.params)
        if (p.name == "format") return param("format").value_or("") == "csv";
    return false;
}

std::optional<json> Ctx::json_body() const {
    if (route.body == Body::OptionalJson && req.body.empty()) return std::nullopt;
    return parse_json_body(req.body);
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

Core::Core(ServerOptions o) : opt(std::move(o)), data_dir(default_data_dir(opt)), series_cache(opt.cache_bytes) {}

Core::~Core() {
    if (lock_fd >= 0) ::close(lock_fd);
}

Role Core::authorize(const httplib::Request& req, Role need, std::string* actor) {
    *actor = "anonymous";
    const auto auth_headers = req.get_header_value_count("Authorization");
    if (auth_headers == 0) {
        // Loopback peers only, and only when the browser says it asked for this machine: a page of
        // another origin whose name was rebound to 127.0.0.1 sends its own name as Host.
        if (need == Role::Read && opt.anonymous_loopback_reads && is_loopback_peer(req.remote_addr) &&
            req.get_header_value_count("Host") == 1 && is_loopback_host_header(req.headers.find("Host")->second))
            return Role::Read;
        throw ApiError(401, "unauthorized", "missing API key: send 'Authorization: Bearer <key>'");
    }
    if (auth_headers > 1) throw ApiError(401, "unauthorized", "send one Authorization header, not several");
    std::string why;
    // The stored value whole: httplib's get_header_value() goes through a C string, so a %00 in the
    // header (httplib decodes it) would cut the value short there and "<key>%00abc" pass as the key.
    const auto token = bearer_token(req.headers.find("Authorization")->second, &why);
    if (!token) throw ApiError(401, "unauthorized", why);
    const std::string& key = *token;
    auto s = session();
    auto found = lookup_api_key(*s, key);
    if (!found) throw ApiError(401, "unauthorized", "unknown API key");
    if (found->revoked_at)
        throw ApiError(401, "unauthorized", fmt::format("API key {} was revoked at {}", found->prefix, *found->revoked_at));
    if (found->last_use_stale) touch_api_key(*s, key);
    *actor = found->prefix;
    if (static_cast<int>(found->role) < static_cast<int>(need))
        throw ApiError(403, "forbidden", fmt::format("this request needs the {} role; the key has {}", role_name(need),
                                                     role_name(found->role)));
    return found->role;
}

namespace {

// The document served: openapi.json's text, the parameters from the route declarations, and the
// run spec's schemas from its parser (force_model::run_spec_schema), so none of them is a second
// list to keep in step by hand.
json full_openapi(const std::vector<RouteSpec>& routes) {
    json doc = openapi_document(json::parse(openapi_base()), routes);
    const json spec = force_model::run_spec_schema();
    json& schemas = doc["components"]["schemas"];
    schemas["RunSpec"] = spec;
    schemas["Tool"] = spec["properties"]["tool"];
    schemas["NumberedTool"] = spec["properties"]["tools"]["items"];
    return doc;
}

// What admission decided for the request being processed on this thread.
struct Admitted {
    std::uint64_t serial = 0;   // current_request_serial() of that request
    Role role = Role::Read;
    std::string actor;
};
thread_local Admitted tl_admitted;

// A body on a route that takes none (curl's -d '' or -d '{}' is fine): beyond this it is refused
// unread, so a route that needs no key never buffers a large body.
constexpr std::size_t kIgnoredBodyBytes = 64u << 10;

}  // namespace

bool Core::admit(const httplib::Request& req, httplib::Response& res) {
    const auto t0 = std::chrono::steady_clock::now();
    const std::uint64_t serial = current_request_serial();
    if (serial != 0 && tl_admitted.serial == serial) return true;   // the Expect: 100-continue hook admitted it
    const bool body = announces_body(req);
    const std::string method = req.method == "HEAD" ? "GET" : req.method;
    const Matcher* m = nullptr;
    for (const Matcher& x : matchers_)
        if (x.spec->method == method && req.path.compare(0, x.literal.size(), x.literal) == 0 &&
            std::regex_match(req.path, x.pattern)) {
            m = &x;
            break;
        }
    auto refuse = [&](int status, const std::string& code, const std::string& message) {
        res.status = status;
        res.set_content(body_text(error_body(code, message)), "application/json");
        if (body) close_after_response(req);
        metrics.request(req.method, m ? m->spec->path : "unmatched", status,
                        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
        return false;
    };
    // A body for no route (static files take none) is never read.
    if (!m) return body ? refuse(404, "not_found", fmt::format("no such resource: {} {}", req.method, req.path)) : true;
    std::uint64_t length = 0;
    if (const std::string text = req.get_header_value("Content-Length"); !text.empty()) {
        const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), length);
        if (ec != std::errc() || end != text.data() + text.size())
            return refuse(400, "bad_request", "Content-Length is not a number");
    }
    const bool chunked = req.get_header_value("Transfer-Encoding").find("chunked") != std::string::npos;
    Admitted a{serial, Role::Read, "anonymous"};
    try {
        if (m->spec->role) a.role = authorize(req, *m->spec->role, &a.actor);
    } catch (const ApiError& e) {
        return refuse(e.status, e.code, e.what());
    } catch (const std::exception& e) {
        spdlog::error("{} {}: {}", req.method, req.path, textio::printable(e.what()));
        return refuse(500, "internal", "database error");
    }
    if (length > opt.max_body_bytes)
        return refuse(413, "payload_too_large",
                      fmt::format("request body of {} bytes exceeds the limit of {} bytes", length, opt.max_body_bytes));
    if (m->spec->body == Body::None && (chunked || length > kIgnoredBodyBytes))
        return refuse(413, "payload_too_large", fmt::format("{} {} takes no request body", m->spec->method, m->spec->path));
    tl_admitted = std::move(a);
    return true;
}

void Core::route(RouteSpec spec, Handler h) {
    const std::string pattern = route_pattern(spec);   // also checks every {name} is declared
    routes.push_back(spec);
    auto r = std::make_shared<const RouteSpec>(std::move(spec));
    matchers_.push_back({r, r->path.substr(0, r->path.find('{')), std::regex(pattern)});
    const std::string method = r->method;
    auto wrapped = [this, r, h](const httplib::Request& req, httplib::Response& res) {
        const auto t0 = std::chrono::steady_clock::now();
        try {
            std::string actor = "anonymous";
            Role role = Role::Read;
            if (const auto serial = current_request_serial(); serial != 0 && tl_admitted.serial == serial) {
                role = tl_admitted.role;   // checked before the body was read
                actor = tl_admitted.actor;
            } else if (r->role) {
                role = authorize(req, *r->role, &actor);
            }
            std::vector<std::string> path_values;
            for (std::size_t i = 1; i < req.matches.size(); ++i) path_values.push_back(req.matches[i].str());
            auto query = [&req](const std::string& name) -> std::optional<std::string> {
                if (!req.has_param(name)) return std::nullopt;
                return req.get_param_value(name);
            };
            Ctx ctx{req, res, *r, read_params(*r, path_values, query), role, actor};
            if (r->body == Body::Multipart && !req.is_multipart_form_data())
                bad_request(fmt::format("{} {} takes multipart/form-data{}", r->method, r->path, r->multipart_hint));
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
            if (!conflict) spdlog::error("{} {}: {}", r->method, req.path, e.what());
            res.set_content(body_text(error_body(conflict ? "conflict" : "internal", conflict ? e.what() : "database error")),
                            "application/json");
        } catch (const std::exception& e) {
            spdlog::error("{} {}: {}", r->method, req.path, textio::printable(e.what()));
            res.status = 500;
            res.set_content(body_text(error_body("internal", e.what())), "application/json");
        }
        compress_answer(req, res);
        metrics.request(r->method, r->path, res.status,
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

// Uploads, NC sources and webhook secrets live in these files: what the server creates gets
// 0666 & ~umask (0600 by default), and the database files and the uploads folder an older version
// left readable lose the masked bits (only removed: a mode narrower than the mask stays so).
static void restrict_file_modes(unsigned file_umask, const std::string& db_path) {
    const mode_t mask = static_cast<mode_t>(file_umask & 0777u);
    ::umask(mask);
    for (const char* suffix : {"", "-wal", "-shm", ".lock"}) {
        const std::string p = db_path + suffix;
        std::error_code ec;
        if (fs::exists(p, ec)) fs::permissions(p, static_cast<fs::perms>(mask), fs::perm_options::remove, ec);
    }
}

Server::Server(ServerOptions opt) : impl_(std::make_unique<Impl>(std::move(opt))) {
    auto& c = *impl_;
    if (db::backend_of(c.opt.db_path) == db::Backend::Sqlite) {
        if (c.opt.workers < 1)
            throw std::runtime_error(fmt::format("--workers {}: no other process can compute the jobs of an SQLite store; "
                                                 "use 1 or more (cutload worker needs PostgreSQL)",
                                                 c.opt.workers));
        restrict_file_modes(c.opt.file_umask, c.opt.db_path);
        // One server per SQLite file: its claims are safe across processes, but re-queueing the
        // jobs left running at start takes every running job for a dead process's.
        c.lock_fd = ::open((c.opt.db_path + ".lock").c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
        if (c.lock_fd < 0 || ::flock(c.lock_fd, LOCK_EX | LOCK_NB) != 0)
            throw std::runtime_error(fmt::format("{} is in use by another cutload serve (lock {}.lock)", c.opt.db_path,
                                                 c.opt.db_path));
    } else {
        // PostgreSQL: no lock file (several processes may share the database; claims lock rows
        // with FOR UPDATE SKIP LOCKED). The umask still applies to uploads.
        ::umask(static_cast<mode_t>(c.opt.file_umask & 0777u));
    }
    c.store = db::Store::open(c.opt.db_path);
    c.store->migrate();
    fs::create_directories(c.data_dir);
    {
        // The folder holds every upload: closing it closes those an older version left readable.
        std::error_code ec;
        fs::permissions(c.data_dir, static_cast<fs::perms>(c.opt.file_umask & 0777u), fs::perm_options::remove, ec);
    }
    const bool shared = db::backend_of(c.opt.db_path) != db::Backend::Sqlite;
    remove_orphan_uploads(c.session()->runs(), c.data_dir, shared);
    c.hooks = std::make_unique<Webhooks>(*c.store, c.opt, c.metrics);
    JobPoolOptions pool{c.opt.workers, c.opt.max_attempts};
    pool.shared_store = shared;
    pool.lease_s = c.opt.lease_s;
    c.jobs = std::make_unique<Jobs>(*c.store, pool, c.metrics,
                                    service_job_kinds(*c.store, c.opt, c.data_dir, c.metrics, [&c] { c.hooks->notify(); }));
    // Before the job workers start: they would re-queue the 'running' runs a dead process left.
    c.live = std::make_unique<LiveRuns>(*c.store, c.opt, [&c] { c.hooks->notify(); });
    c.live->recover();

    GateLimits limits;
    limits.threads = std::max(4, c.opt.http_threads);
    limits.header_timeout_s = c.opt.header_timeout_s;
    limits.idle_timeout_s = c.opt.keep_alive_s;
    limits.read_timeout_s = c.opt.body_read_timeout_s;
    limits.body_timeout_s = c.opt.body_timeout_s;
    limits.max_header_bytes = c.opt.max_header_bytes;
    limits.max_waiting = c.opt.max_waiting_connections;
    limits.max_body_bytes = c.opt.max_body_bytes;
    c.http.set_limits(limits);
    c.http.set_keep_alive_max_count(100000);
    // Without it, Nagle's algorithm and delayed ACKs hold small responses for ~40 ms.
    c.http.set_tcp_nodelay(true);
    // Debian's httplib compresses with brotli at its slowest setting whenever a client offers "br"
    // (measured: 1.7-2.0 s for a 627 KB forces window, against 0.05 s with gzip), and every
    // browser offers it. Drop "br" from the offer before routing so large answers go out gzipped.
    // The request object is httplib's own mutable local; only the handler signature is const.
    // Keys before bodies: a request is admitted (route, key, role, announced size) on its headers,
    // before httplib reads its body; a client that asks "Expect: 100-continue" hears the refusal
    // before it sends the body.
    c.http.set_expect_100_continue_handler([&c](const httplib::Request& req, httplib::Response& res) {
        return c.admit(req, res) ? 100 : res.status;
    });
    c.http.set_pre_routing_handler([&c](const httplib::Request& req, httplib::Response& res) {
        if (!c.admit(req, res)) return httplib::Server::HandlerResponse::Handled;
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

    add_all_routes(c);
    c.openapi = full_openapi(c.routes).dump(1);
}

Server::~Server() { stop(); }

void Server::start() {
    auto& c = *impl_;
    c.bound_port = c.opt.port == 0 ? c.http.bind_to_any_port(c.opt.host) : (c.http.bind_to_port(c.opt.host, c.opt.port) ? c.opt.port : -1);
    if (c.bound_port < 0) throw std::runtime_error(fmt::format("cannot listen on {}:{}", c.opt.host, c.opt.port));
    c.http.widen_backlog(std::max(128, c.opt.max_waiting_connections));
    c.jobs->start();
    c.hooks->start();
    c.listener = std::thread([&c] { c.http.listen_after_bind(); });
    c.started = true;
    spdlog::info("cutload serve: listening on http://{}:{} (db {}, {} worker(s))", c.opt.host, c.bound_port,
                 db::printable_location(c.opt.db_path), c.opt.workers);
}

void Server::stop() {
    auto& c = *impl_;
    {
        std::lock_guard lk(c.mu);
        if (c.stopped) return;
        c.stopped = true;
    }
    c.stopping = true;
    if (c.started) {
        c.http.stop();
        if (c.listener.joinable()) c.listener.join();
    }
    c.live->stop_all();   // each live run closes as a finished run
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

std::vector<std::pair<std::string, std::string>> Server::routes() const {
    std::vector<std::pair<std::string, std::string>> out;
    for (const RouteSpec& r : impl_->routes) out.emplace_back(r.method, r.path);
    return out;
}

void add_all_routes(Core& c) {
    add_library_routes(c);
    add_run_routes(c);
    add_program_routes(c);
    add_measurement_routes(c);
    add_calibration_routes(c);
    add_alert_routes(c);
    add_misc_routes(c);
    add_view_routes(c);
    add_live_routes(c);
}

const std::string& openapi_json() {
    // The routes of a server with the default options (a route's bounds may follow the options:
    // each server serves its own document).
    static const std::string doc = [] {
        Core c{ServerOptions{}};
        add_all_routes(c);
        return full_openapi(c.routes).dump(1);
    }();
    return doc;
}

}  // namespace cutload::server
