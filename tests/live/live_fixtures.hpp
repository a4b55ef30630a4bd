// Shared by the live tests: collecting what a source delivers, a scripted raw TCP adapter for
// protocol corner cases, and the demo log read independently of cutload's readers.
#pragma once

#include "live/live.hpp"
#include "live/shdr_client.hpp"

#include <catch2/catch.hpp>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <charconv>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace cutload::live::test {

using Clock = std::chrono::steady_clock;
using namespace std::chrono_literals;

inline std::string source_path(const std::string& rel) { return std::string(CUTLOAD_SOURCE_DIR) + "/" + rel; }
inline std::string okuma_log() { return std::string(CUTLOAD_SHARED_DIR) + "/data/real/okuma_multus_shdr/okuma.txt"; }
// A scratch file name of this process: several worktrees may run the suite at once.
inline std::string temp_path(const std::string& name) {
    return (std::filesystem::temp_directory_path() / ("cutload_live_" + std::to_string(::getpid()) + "_" + name)).string();
}

struct Timed {
    SourceEvent event;
    Clock::time_point seen;
};

// Everything a source delivered, with when it arrived.
struct Collected {
    std::vector<Observation> observations;
    std::vector<Clock::time_point> arrived;   // per observation
    std::vector<Timed> events;
    std::size_t count(EventKind k) const {
        std::size_t n = 0;
        for (const auto& e : events) n += e.event.kind == k;
        return n;
    }
    const SourceEvent* first(EventKind k) const {
        for (const auto& e : events)
            if (e.event.kind == k) return &e.event;
        return nullptr;
    }
};

// Calls next() until `done` says so or `timeout` passes; returns whether `done` was reached.
inline bool collect(Source& src, Collected& c, const std::function<bool(const Collected&)>& done,
                    std::chrono::milliseconds timeout) {
    const std::atomic<bool> cancel{false};
    const auto deadline = Clock::now() + timeout;
    Batch b;
    while (Clock::now() < deadline) {
        src.next(b, 50ms, cancel);
        const auto now = Clock::now();
        for (auto& o : b.observations) {
            c.observations.push_back(std::move(o));
            c.arrived.push_back(now);
        }
        for (auto& e : b.events) c.events.push_back({std::move(e), now});
        if (done(c)) return true;
    }
    return false;
}

// The same for the raw line client.
struct CollectedLines {
    std::vector<std::string> lines;
    std::vector<Timed> events;
};
inline bool collect_lines(ShdrClient& client, CollectedLines& c, const std::function<bool(const CollectedLines&)>& done,
                          std::chrono::milliseconds timeout) {
    const std::atomic<bool> cancel{false};
    const auto deadline = Clock::now() + timeout;
    LineBatch b;
    while (Clock::now() < deadline) {
        client.next(b, 50ms, cancel);
        const auto now = Clock::now();
        for (auto& l : b.lines) c.lines.push_back(std::move(l));
        for (auto& e : b.events) c.events.push_back({std::move(e), now});
        if (done(c)) return true;
    }
    return false;
}

// A one-connection TCP server on 127.0.0.1 that runs `script` with the accepted socket on its
// own thread: an adapter that misbehaves exactly as a test needs.
class ScriptedAdapter {
public:
    using Script = std::function<void(int fd, const std::atomic<bool>& stop)>;
    explicit ScriptedAdapter(Script script) {
        listen_fd_ = ::socket(AF_INET, SOCK_STREAM, 0);
        const int one = 1;
        ::setsockopt(listen_fd_, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
        sockaddr_in a{};
        a.sin_family = AF_INET;
        a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
        REQUIRE(::bind(listen_fd_, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0);
        REQUIRE(::listen(listen_fd_, 4) == 0);
        socklen_t len = sizeof a;
        ::getsockname(listen_fd_, reinterpret_cast<sockaddr*>(&a), &len);
        port_ = ntohs(a.sin_port);
        thread_ = std::thread([this, script = std::move(script)] {
            const int fd = ::accept(listen_fd_, nullptr, nullptr);
            if (fd < 0) return;
            script(fd, stop_);
            ::close(fd);
        });
    }
    ~ScriptedAdapter() {
        stop_ = true;
        ::shutdown(listen_fd_, SHUT_RDWR);
        ::close(listen_fd_);
        thread_.join();
    }
    int port() const { return port_; }

private:
    int listen_fd_ = -1;
    int port_ = 0;
    std::atomic<bool> stop_{false};
    std::thread thread_;
};

inline void send_text(int fd, const std::string& s) { (void)!::send(fd, s.data(), s.size(), MSG_NOSIGNAL); }

// Reads one '\n'-terminated line (false on EOF, error, or stop).
inline bool read_line(int fd, std::string& line, const std::atomic<bool>& stop) {
    line.clear();
    char ch;
    while (!stop) {
        const ssize_t n = ::recv(fd, &ch, 1, 0);
        if (n <= 0) return false;
        if (ch == '\n') return true;
        line += ch;
    }
    return false;
}

// One reading of data/demo_dryrun.csv, read here with a plain parser of its known layout
// (t_spindle,spindle,t_feed,feed,t_pos,x,y,z,block), not with cutload's CSV reader.
struct DemoReading {
    double t_s;
    enum Kind { Spindle, Feed, Pos, Block } kind;
    double v[3];
    std::string block;
};

inline std::vector<DemoReading> demo_readings() {
    std::ifstream in(source_path("data/demo_dryrun.csv"));
    REQUIRE(in);
    std::string line;
    std::getline(in, line);
    REQUIRE(line.rfind("t_spindle [s],spindle [rpm],t_feed [s],feed [mm/min],t_pos [s],x [mm],y [mm],z [mm],block", 0) == 0);
    std::vector<DemoReading> out;
    while (std::getline(in, line)) {
        std::vector<std::string> f;
        std::stringstream ss(line);
        std::string cell;
        while (std::getline(ss, cell, ',')) f.push_back(cell);
        REQUIRE(f.size() == 9);
        const auto num = [](const std::string& s) { return std::strtod(s.c_str(), nullptr); };
        // In a row the stamps increase t_spindle < t_feed < t_pos; the block shares t_pos.
        out.push_back({num(f[0]), DemoReading::Spindle, {num(f[1]), 0, 0}, {}});
        out.push_back({num(f[2]), DemoReading::Feed, {num(f[3]), 0, 0}, {}});
        out.push_back({num(f[4]), DemoReading::Pos, {num(f[5]), num(f[6]), num(f[7])}, {}});
        out.push_back({num(f[4]), DemoReading::Block, {0, 0, 0}, f[8]});
    }
    return out;
}

inline std::vector<double> numbers(const std::string& text) {
    std::vector<double> v;
    std::stringstream ss(text);
    double x;
    while (ss >> x) v.push_back(x);
    return v;
}

}  // namespace cutload::live::test
