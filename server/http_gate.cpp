#include "http_gate.hpp"

#include <fmt/format.h>
#include <netdb.h>
#include <poll.h>
#include <spdlog/spdlog.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <mutex>
#include <thread>
#include <vector>

namespace cutload::server {
namespace {

using Clock = std::chrono::steady_clock;

// After a refusal whose body was not read: what is discarded before closing, so that the client
// reads the answer instead of a connection reset.
constexpr std::size_t kDrainBytes = 8u << 20;
constexpr double kDrainS = 2;
// Chunk headers and trailers on top of a chunked body's data.
constexpr std::size_t kChunkFramingBytes = 64u << 10;

Clock::time_point after(double s) {
    return Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(s));
}

int ms_until(Clock::time_point t) {
    const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(t - Clock::now()).count() + 1;
    return static_cast<int>(std::clamp<long long>(ms, 0, 1000));
}

bool wait_for(int fd, short events, int timeout_ms) {
    pollfd p{fd, events, 0};
    int r;
    do r = ::poll(&p, 1, timeout_ms);
    while (r < 0 && errno == EINTR);
    return r > 0;
}

void address_of(int fd, bool peer, std::string& ip, int& port) {
    sockaddr_storage a{};
    socklen_t len = sizeof a;
    if ((peer ? ::getpeername(fd, reinterpret_cast<sockaddr*>(&a), &len) : ::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len)) != 0)
        return;
    char host[NI_MAXHOST] = "", serv[NI_MAXSERV] = "";
    if (::getnameinfo(reinterpret_cast<sockaddr*>(&a), len, host, sizeof host, serv, sizeof serv, NI_NUMERICHOST | NI_NUMERICSERV) == 0) {
        ip = host;
        port = std::atoi(serv);
    }
}

// One answer written by the gate itself (no request was parsed): best effort, never blocking.
void answer_and_close(int fd, int status, const char* reason, const std::string& code, const std::string& message) {
    const std::string body = fmt::format(R"({{"error":{{"code":"{}","message":"{}"}}}})", code, message);
    const std::string out = fmt::format("HTTP/1.1 {} {}\r\nContent-Type: application/json\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{}",
                                        status, reason, body.size(), body);
    (void)::send(fd, out.data(), out.size(), MSG_DONTWAIT | MSG_NOSIGNAL);
    ::shutdown(fd, SHUT_RDWR);
    ::close(fd);
}

struct Conn {
    int fd = -1;
    std::string buf;      // bytes received and not yet consumed, from `pos`
    std::size_t pos = 0;
    enum class Phase { Header, Idle, Drain } phase = Phase::Header;
    Clock::time_point since, deadline;
    std::size_t drained = 0;

    std::size_t pending() const { return buf.size() - pos; }
    bool header_complete() const { return buf.find("\r\n\r\n", pos) != std::string::npos; }
    void consume_front() {
        if (pos == buf.size()) {
            buf.clear();
            pos = 0;
        } else if (pos > (64u << 10)) {
            buf.erase(0, pos);
            pos = 0;
        }
    }
};

// What a request hook says about the request running on this thread.
struct RequestState {
    bool close = false;
};
thread_local RequestState* tl_request = nullptr;
thread_local std::uint64_t tl_serial = 0;
std::atomic<std::uint64_t> next_serial{1};

// httplib's Stream over a gated connection: the buffered header bytes first, then the socket under
// the body's deadlines.
class GateStream : public httplib::Stream {
public:
    GateStream(Conn& c, const GateLimits& lim) : c_(c), lim_(lim) {}

    void start_body(const httplib::Request& req) {
        in_body_ = true;
        body_deadline_ = after(lim_.body_timeout_s);
        chunked_ = req.get_header_value("Transfer-Encoding").find("chunked") != std::string::npos;
        const std::string len = req.get_header_value("Content-Length");
        announced_ = len.empty() ? 0 : std::strtoull(len.c_str(), nullptr, 10);
    }
    // Whether the connection is at the start of the next request: the body (if any) was read whole.
    bool at_request_boundary() const { return !chunked_ && body_read_ == announced_; }

    bool is_readable() const override {
        return c_.pending() > 0 || wait_for(c_.fd, POLLIN, static_cast<int>(lim_.read_timeout_s * 1000));
    }
    bool is_writable() const override { return wait_for(c_.fd, POLLOUT, static_cast<int>(lim_.read_timeout_s * 1000)); }

    ssize_t read(char* ptr, size_t size) override {
        if (c_.pending() > 0) {
            const std::size_t n = std::min(size, c_.pending());
            std::memcpy(ptr, c_.buf.data() + c_.pos, n);
            c_.pos += n;
            c_.consume_front();
            return counted(n);
        }
        // The gate hands over whole header blocks: reading past one before the body means a
        // malformed request.
        if (!in_body_) return -1;
        if (Clock::now() >= body_deadline_) return -1;
        const int wait_ms = static_cast<int>(std::min<double>(lim_.read_timeout_s * 1000,
                                                              std::chrono::duration<double, std::milli>(body_deadline_ - Clock::now()).count()));
        if (!wait_for(c_.fd, POLLIN, std::max(wait_ms, 0))) return -1;
        const ssize_t n = ::recv(c_.fd, ptr, size, 0);
        if (n <= 0) return n < 0 ? -1 : 0;
        return counted(static_cast<std::size_t>(n));
    }

    ssize_t write(const char* ptr, size_t size) override {
        // SO_SNDTIMEO (httplib's write time-out) bounds a send to a client that does not read.
        const ssize_t n = ::send(c_.fd, ptr, size, MSG_NOSIGNAL);
        return n < 0 ? -1 : n;
    }

    void get_remote_ip_and_port(std::string& ip, int& port) const override { address_of(c_.fd, true, ip, port); }
    void get_local_ip_and_port(std::string& ip, int& port) const override { address_of(c_.fd, false, ip, port); }
    socket_t socket() const override { return c_.fd; }

private:
    ssize_t counted(std::size_t n) {
        if (in_body_) {
            body_read_ += n;
            // Content-Length beyond the limit is refused before the body; this bounds chunked bodies.
            if (body_read_ > lim_.max_body_bytes + kChunkFramingBytes) return -1;
        }
        return static_cast<ssize_t>(n);
    }

    Conn& c_;
    const GateLimits& lim_;
    bool in_body_ = false, chunked_ = false;
    std::size_t announced_ = 0, body_read_ = 0;
    Clock::time_point body_deadline_;
};

}  // namespace

struct GatedHttpServer::Impl {
    explicit Impl(GatedHttpServer& owner) : owner(owner) {}

    GatedHttpServer& owner;
    GateLimits lim;

    std::mutex mu;
    std::condition_variable work_cv;
    std::deque<std::unique_ptr<Conn>> incoming;   // to the gate: new and returning connections
    std::deque<std::unique_ptr<Conn>> ready;      // to the request threads: whole header blocks
    bool stopping = false;
    int wake_fd = -1;
    std::thread gate;
    std::vector<std::thread> workers;

    std::atomic<long> header_timeouts{0}, header_too_large{0}, evicted{0};

    void start() {
        stopping = false;
        wake_fd = ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
        if (wake_fd < 0) throw std::runtime_error(fmt::format("eventfd: {}", std::strerror(errno)));
        gate = std::thread([this] { gate_loop(); });
        for (int i = 0; i < std::max(1, lim.threads); ++i) workers.emplace_back([this] { worker_loop(); });
    }

    void stop() {
        {
            std::lock_guard lk(mu);
            stopping = true;
        }
        wake();
        work_cv.notify_all();
        if (gate.joinable()) gate.join();
        for (auto& t : workers)
            if (t.joinable()) t.join();
        workers.clear();
        std::lock_guard lk(mu);
        for (auto& c : incoming) ::close(c->fd);
        for (auto& c : ready) ::close(c->fd);
        incoming.clear();
        ready.clear();
        if (wake_fd >= 0) ::close(wake_fd);
        wake_fd = -1;
    }

    void wake() const {
        if (wake_fd < 0) return;
        const std::uint64_t one = 1;
        (void)!::write(wake_fd, &one, sizeof one);
    }

    void admit(std::unique_ptr<Conn> c) {
        {
            std::lock_guard lk(mu);
            if (stopping) {
                ::close(c->fd);
                return;
            }
            incoming.push_back(std::move(c));
        }
        wake();
    }

    void dispatch(std::unique_ptr<Conn> c) {
        {
            std::lock_guard lk(mu);
            ready.push_back(std::move(c));
        }
        work_cv.notify_one();
    }

    void gate_loop() {
        std::vector<std::unique_ptr<Conn>> waiting;
        std::vector<pollfd> fds;
        char chunk[16384];
        for (;;) {
            {
                std::lock_guard lk(mu);
                if (stopping) break;
                while (!incoming.empty()) {
                    waiting.push_back(std::move(incoming.front()));
                    incoming.pop_front();
                }
            }
            // A returning connection may hold the next request already (pipelining).
            for (auto& c : waiting)
                if (c && c->phase != Conn::Phase::Drain && c->header_complete()) dispatch(std::move(c));
            std::erase(waiting, nullptr);
            // The cap: the connection waiting longest goes first (a client sending its headers
            // at a normal pace is among the newest).
            while (static_cast<int>(waiting.size()) > lim.max_waiting) {
                auto oldest = std::min_element(waiting.begin(), waiting.end(),
                                               [](const auto& a, const auto& b) { return a->since < b->since; });
                ::shutdown((*oldest)->fd, SHUT_RDWR);
                ::close((*oldest)->fd);
                waiting.erase(oldest);
                ++evicted;
            }

            fds.assign(1, pollfd{wake_fd, POLLIN, 0});
            Clock::time_point next = after(1);
            for (const auto& c : waiting) {
                fds.push_back(pollfd{c->fd, POLLIN, 0});
                next = std::min(next, c->deadline);
            }
            if (::poll(fds.data(), fds.size(), ms_until(next)) < 0 && errno != EINTR) {
                spdlog::error("http gate: poll: {}", std::strerror(errno));
                std::this_thread::sleep_for(std::chrono::milliseconds(10));
                continue;
            }
            if (fds[0].revents) {
                std::uint64_t v;
                while (::read(wake_fd, &v, sizeof v) > 0) {
                }
            }
            const auto now = Clock::now();
            for (std::size_t i = 0; i < waiting.size(); ++i) {
                Conn& c = *waiting[i];
                bool closed = false, ready_now = false;
                if (fds[i + 1].revents) {
                    const ssize_t n = ::recv(c.fd, chunk, sizeof chunk, MSG_DONTWAIT);
                    if (n == 0 || (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR)) {
                        ::close(c.fd);
                        closed = true;
                    } else if (n > 0 && c.phase == Conn::Phase::Drain) {
                        c.drained += static_cast<std::size_t>(n);
                        if (c.drained > kDrainBytes) {
                            ::close(c.fd);
                            closed = true;
                        }
                    } else if (n > 0) {
                        if (c.phase == Conn::Phase::Idle) {
                            c.phase = Conn::Phase::Header;
                            c.deadline = now + std::chrono::duration_cast<Clock::duration>(
                                                   std::chrono::duration<double>(lim.header_timeout_s));
                        }
                        const std::size_t from = c.buf.size() >= c.pos + 3 ? c.buf.size() - 3 : c.pos;
                        c.buf.append(chunk, static_cast<std::size_t>(n));
                        if (c.buf.find("\r\n\r\n", from) != std::string::npos) {
                            ready_now = true;
                        } else if (c.pending() > lim.max_header_bytes) {
                            ++header_too_large;
                            answer_and_close(c.fd, 431, "Request Header Fields Too Large", "headers_too_large",
                                             fmt::format("request line and headers exceed {} bytes", lim.max_header_bytes));
                            closed = true;
                        }
                    }
                }
                if (!closed && !ready_now && now >= c.deadline) {
                    if (c.phase == Conn::Phase::Header && c.pending() > 0) {
                        ++header_timeouts;
                        answer_and_close(c.fd, 408, "Request Timeout", "request_timeout",
                                         fmt::format("request line and headers not complete within {} s", lim.header_timeout_s));
                    } else {
                        ::shutdown(c.fd, SHUT_RDWR);
                        ::close(c.fd);
                    }
                    closed = true;
                }
                if (ready_now) dispatch(std::move(waiting[i]));
                else if (closed) waiting[i].reset();
            }
            std::erase(waiting, nullptr);
        }
        for (auto& c : waiting) ::close(c->fd);
    }

    void worker_loop() {
        for (;;) {
            std::unique_ptr<Conn> c;
            {
                std::unique_lock lk(mu);
                work_cv.wait(lk, [this] { return stopping || !ready.empty(); });
                if (stopping) return;
                c = std::move(ready.front());
                ready.pop_front();
            }
            serve(std::move(c));
        }
    }

    void serve(std::unique_ptr<Conn> c) {
        GateStream strm(*c, lim);
        RequestState state;
        tl_request = &state;
        bool connection_closed = false;
        bool ok = false;
        try {
            ok = owner.process_request(strm, false, connection_closed, [&strm](httplib::Request& req) {
                tl_serial = next_serial++;
                strm.start_body(req);
            });
        } catch (const std::exception& e) {
            spdlog::error("http: {}", e.what());
        }
        tl_request = nullptr;
        tl_serial = 0;
        bool stop_now;
        {
            std::lock_guard lk(mu);
            stop_now = stopping;
        }
        if (ok && !connection_closed && !state.close && strm.at_request_boundary() && !stop_now) {
            c->phase = Conn::Phase::Idle;
            c->since = Clock::now();
            c->deadline = after(lim.idle_timeout_s);
            admit(std::move(c));
        } else if (ok && state.close && !stop_now) {
            // The body was never read: no more requests, but let the client read the answer.
            ::shutdown(c->fd, SHUT_WR);
            c->phase = Conn::Phase::Drain;
            c->buf.clear();
            c->pos = 0;
            c->since = Clock::now();
            c->deadline = after(kDrainS);
            admit(std::move(c));
        } else {
            ::shutdown(c->fd, SHUT_RDWR);
            ::close(c->fd);
        }
    }
};

namespace {

// httplib hands each accepted socket to a task queue: this one passes it straight to the gate
// (the gate never blocks), and its shutdown stops the gate and the request threads.
class GateQueue : public httplib::TaskQueue {
public:
    explicit GateQueue(std::shared_ptr<GatedHttpServer::Impl> impl) : impl_(std::move(impl)) { impl_->start(); }
    void enqueue(std::function<void()> fn) override { fn(); }
    void shutdown() override { impl_->stop(); }

private:
    std::shared_ptr<GatedHttpServer::Impl> impl_;
};

}  // namespace

GatedHttpServer::GatedHttpServer() : impl_(std::make_shared<Impl>(*this)) {
    new_task_queue = [impl = impl_] { return new GateQueue(impl); };
}

GatedHttpServer::~GatedHttpServer() = default;

void GatedHttpServer::set_limits(const GateLimits& limits) {
    impl_->lim = limits;
    set_payload_max_length(limits.max_body_bytes);
    set_read_timeout(std::chrono::duration<double>(limits.read_timeout_s));
    set_keep_alive_timeout(static_cast<time_t>(std::max(1.0, limits.idle_timeout_s)));
}

GatedHttpServer::Counters GatedHttpServer::counters() const {
    return {impl_->header_timeouts.load(), impl_->header_too_large.load(), impl_->evicted.load()};
}

void GatedHttpServer::widen_backlog(int connections) {
    // listen() again on a listening socket sets its backlog anew.
    if (svr_sock_ != INVALID_SOCKET && ::listen(svr_sock_, connections) != 0)
        spdlog::warn("http: listen backlog {}: {}", connections, std::strerror(errno));
}

bool GatedHttpServer::process_and_close_socket(socket_t sock) {
    auto c = std::make_unique<Conn>();
    c->fd = sock;
    c->phase = Conn::Phase::Header;
    c->since = Clock::now();
    // From the connection on: a client that connects and sends nothing is as slow as one that
    // sends its headers a line at a time.
    c->deadline = after(impl_->lim.header_timeout_s);
    impl_->admit(std::move(c));
    return true;
}

void close_after_response(const httplib::Request& req) {
    // The request is httplib's own mutable local; only the handler signature is const.
    auto& headers = const_cast<httplib::Headers&>(req.headers);
    headers.erase("Connection");
    headers.emplace("Connection", "close");
    if (tl_request) tl_request->close = true;
}

std::uint64_t current_request_serial() { return tl_serial; }

bool announces_body(const httplib::Request& req) {
    if (req.get_header_value("Transfer-Encoding").find("chunked") != std::string::npos) return true;
    const std::string len = req.get_header_value("Content-Length");
    return !len.empty() && len != "0";
}

}  // namespace cutload::server
