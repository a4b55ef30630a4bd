// Shared by the server tests that play a hostile or broken client: requests written byte for byte
// on a plain TCP socket (headers no HTTP library would send, bodies never sent, headers sent a
// line at a time), and the answer's status line read back.
#pragma once

#include <arpa/inet.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <string>

namespace cutload::test {

// A connected loopback socket, or -1.
inline int connect_loopback(int port) {
    const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (fd < 0) return -1;
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<std::uint16_t>(port));
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (::connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) {
        ::close(fd);
        return -1;
    }
    return fd;
}

inline bool send_all(int fd, const std::string& bytes) {
    std::size_t off = 0;
    while (off < bytes.size()) {
        const ssize_t n = ::send(fd, bytes.data() + off, bytes.size() - off, MSG_NOSIGNAL);
        if (n <= 0) return false;
        off += static_cast<std::size_t>(n);
    }
    return true;
}

// What arrived within timeout_ms, up to the end of the headers and `Content-Length` bytes of body
// (or until the server closed).
inline std::string read_answer(int fd, int timeout_ms) {
    std::string in;
    const auto until = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
    char buf[8192];
    for (;;) {
        const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(until - std::chrono::steady_clock::now()).count();
        if (left <= 0) break;
        pollfd p{fd, POLLIN, 0};
        if (::poll(&p, 1, static_cast<int>(left)) <= 0) break;
        const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
        if (n <= 0) break;
        in.append(buf, static_cast<std::size_t>(n));
        const auto end = in.find("\r\n\r\n");
        if (end == std::string::npos) continue;
        const auto cl = in.find("Content-Length: ");
        if (cl == std::string::npos || cl > end) break;
        if (in.size() >= end + 4 + std::stoul(in.substr(cl + 16))) break;
    }
    return in;
}

// The status code of an answer ("HTTP/1.1 401 Unauthorized..."), or 0 when there is none.
inline int status_of(const std::string& answer) {
    if (answer.rfind("HTTP/1.", 0) != 0 || answer.size() < 12) return 0;
    return std::atoi(answer.c_str() + 9);
}

// One request on a fresh connection; the answer (empty when none came within timeout_ms).
inline std::string raw_request(int port, const std::string& bytes, int timeout_ms = 5000) {
    const int fd = connect_loopback(port);
    if (fd < 0) return "";
    std::string answer;
    if (send_all(fd, bytes)) answer = read_answer(fd, timeout_ms);
    ::close(fd);
    return answer;
}

// The body of an answer (after the blank line).
inline std::string body_of(const std::string& answer) {
    const auto end = answer.find("\r\n\r\n");
    return end == std::string::npos ? "" : answer.substr(end + 4);
}

}  // namespace cutload::test
