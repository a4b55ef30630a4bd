// Private to live: the few POSIX socket operations the SHDR client and the replay adapter share.
#pragma once

#include <atomic>
#include <chrono>
#include <string>

namespace cutload::live::net {

// Owns a file descriptor.
class Fd {
public:
    Fd() = default;
    explicit Fd(int fd) : fd_(fd) {}
    Fd(Fd&& o) noexcept : fd_(o.release()) {}
    Fd& operator=(Fd&& o) noexcept;
    Fd(const Fd&) = delete;
    Fd& operator=(const Fd&) = delete;
    ~Fd() { reset(); }
    int get() const { return fd_; }
    explicit operator bool() const { return fd_ >= 0; }
    int release() {
        const int f = fd_;
        fd_ = -1;
        return f;
    }
    void reset(int fd = -1);

private:
    int fd_ = -1;
};

// Connects to host:port (every address the name resolves to, in turn) within `timeout`, giving up
// early when `cancel` is set. Returns a connected, non-blocking socket with TCP_NODELAY, or an
// empty Fd and the reason in `error`.
Fd connect_tcp(const std::string& host, int port, std::chrono::milliseconds timeout, const std::atomic<bool>& cancel,
               std::string& error);

// A non-blocking listening socket on host:port (port 0: any free port; SO_REUSEADDR so a restarted
// adapter gets its port back). Throws std::runtime_error naming the address and why.
Fd listen_tcp(const std::string& host, int port, int& bound_port);

void set_nonblocking(int fd);

}  // namespace cutload::live::net
