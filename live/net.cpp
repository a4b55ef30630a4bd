// POSIX sockets for the SHDR client and the replay adapter (live/net.hpp).
#include "net.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cstring>
#include <stdexcept>
#include <thread>

#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

namespace cutload::live::net {

Fd& Fd::operator=(Fd&& o) noexcept {
    if (this != &o) reset(o.release());
    return *this;
}

void Fd::reset(int fd) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = fd;
}

void set_nonblocking(int fd) {
    const int flags = ::fcntl(fd, F_GETFL, 0);
    ::fcntl(fd, F_SETFL, flags | O_NONBLOCK);
}

namespace {

struct AddrInfo {
    addrinfo* list = nullptr;
    ~AddrInfo() {
        if (list) ::freeaddrinfo(list);
    }
};

int resolve(const std::string& host, int port, bool passive, AddrInfo& out) {
    addrinfo hints{};
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = SOCK_STREAM;
    hints.ai_flags = passive ? AI_PASSIVE : AI_ADDRCONFIG;
    const std::string service = std::to_string(port);
    return ::getaddrinfo(host.empty() ? nullptr : host.c_str(), service.c_str(), &hints, &out.list);
}

}  // namespace

Fd connect_tcp(const std::string& host, int port, std::chrono::milliseconds timeout, const std::atomic<bool>& cancel,
               std::string& error) {
    using Clock = std::chrono::steady_clock;
    const auto deadline = Clock::now() + timeout;
    AddrInfo ai;
    if (const int rc = resolve(host, port, false, ai); rc != 0) {
        error = fmt::format("cannot resolve {}: {}", host, ::gai_strerror(rc));
        return {};
    }
    error = fmt::format("no address for {}", host);
    for (const addrinfo* a = ai.list; a; a = a->ai_next) {
        Fd fd(::socket(a->ai_family, a->ai_socktype | SOCK_CLOEXEC, a->ai_protocol));
        if (!fd) {
            error = fmt::format("socket: {}", std::strerror(errno));
            continue;
        }
        set_nonblocking(fd.get());
        if (::connect(fd.get(), a->ai_addr, a->ai_addrlen) != 0 && errno != EINPROGRESS) {
            error = std::strerror(errno);
            continue;
        }
        // Wait for the handshake in short slices so that a cancel is seen promptly.
        bool done = false;
        while (!done) {
            if (cancel.load()) {
                error = "cancelled";
                return {};
            }
            const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count();
            if (left <= 0) {
                error = fmt::format("no answer within {} ms", timeout.count());
                break;
            }
            pollfd p{fd.get(), POLLOUT, 0};
            const int n = ::poll(&p, 1, static_cast<int>(std::min<long long>(left, 50)));
            if (n < 0 && errno != EINTR) {
                error = fmt::format("poll: {}", std::strerror(errno));
                break;
            }
            if (n > 0) done = true;
        }
        if (!done) continue;
        int so_error = 0;
        socklen_t len = sizeof so_error;
        ::getsockopt(fd.get(), SOL_SOCKET, SO_ERROR, &so_error, &len);
        if (so_error != 0) {
            error = std::strerror(so_error);
            continue;
        }
        const int one = 1;
        ::setsockopt(fd.get(), IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
        ::setsockopt(fd.get(), SOL_SOCKET, SO_KEEPALIVE, &one, sizeof one);
        error.clear();
        return fd;
    }
    return {};
}

Fd listen_tcp(const std::string& host, int port, int& bound_port) {
    AddrInfo ai;
    if (const int rc = resolve(host, port, true, ai); rc != 0)
        throw std::runtime_error(fmt::format("cannot resolve {}: {}", host, ::gai_strerror(rc)));
    std::string error = "no address";
    for (const addrinfo* a = ai.list; a; a = a->ai_next) {
        Fd fd(::socket(a->ai_family, a->ai_socktype | SOCK_CLOEXEC, a->ai_protocol));
        if (!fd) continue;
        const int one = 1;
        ::setsockopt(fd.get(), SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
        if (::bind(fd.get(), a->ai_addr, a->ai_addrlen) != 0 || ::listen(fd.get(), 16) != 0) {
            error = std::strerror(errno);
            continue;
        }
        sockaddr_storage addr{};
        socklen_t len = sizeof addr;
        ::getsockname(fd.get(), reinterpret_cast<sockaddr*>(&addr), &len);
        bound_port = addr.ss_family == AF_INET6 ? ntohs(reinterpret_cast<sockaddr_in6*>(&addr)->sin6_port)
                                                : ntohs(reinterpret_cast<sockaddr_in*>(&addr)->sin_port);
        set_nonblocking(fd.get());
        return fd;
    }
    throw std::runtime_error(fmt::format("cannot listen on {}:{}: {}", host, port, error));
}

}  // namespace cutload::live::net
