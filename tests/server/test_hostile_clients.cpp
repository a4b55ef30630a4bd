// Clients that try to take the real `cutload serve` down without a key: large bodies announced on
// requests that will be refused (the key is checked on the headers, the body never read), and
// slow connections that send a header line every 2 s (they wait in the connection gate, not on
// a request thread, and are cut off at the header deadline). The tests print what they measure:
// the server's RSS before and after, /healthz latencies under the slow connections.
#include "harness.hpp"
#include "raw_http.hpp"

#include <fcntl.h>
#include <sys/wait.h>

#include <algorithm>
#include <atomic>
#include <csignal>
#include <cstdio>
#include <numeric>
#include <regex>
#include <vector>

using namespace cutload::test;

namespace {

std::string read_text(const fs::path& p) {
    std::ifstream in(p);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

// A `cutload serve` child on a free loopback port with an admin and a read key; killed at the end.
struct Served {
    explicit Served(std::vector<std::string> extra = {}) {
        db = store_location(dir.path(), "h.db");
        log = dir.path() / "serve.log";
        admin_key = cutload::server::create_api_key(db.string(), cutload::server::Role::Admin, "admin");
        read_key = cutload::server::create_api_key(db.string(), cutload::server::Role::Read, "reader");
        std::vector<std::string> args{CUTLOAD_BINARY, "serve", "--listen", "127.0.0.1:0", "--db", db.string(),
                                      "--workers", "1", "--device", "cpu", "--drain-s", "0"};
        if (on_postgres()) args.insert(args.end(), {"--data-dir", (dir.path() / "data").string()});
        args.insert(args.end(), extra.begin(), extra.end());
        pid = ::fork();
        REQUIRE(pid >= 0);
        if (pid == 0) {
            const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0600);
            ::dup2(fd, 1);
            ::dup2(fd, 2);
            std::vector<char*> argv;
            for (auto& a : args) argv.push_back(a.data());
            argv.push_back(nullptr);
            ::execv(argv[0], argv.data());
            ::_exit(127);
        }
        static const std::regex listening(R"(listening on http://127\.0\.0\.1:(\d+))");
        for (int i = 0; i < 1000 && port == 0; ++i) {
            std::this_thread::sleep_for(std::chrono::milliseconds(10));
            std::smatch m;
            const std::string out = read_text(log);
            if (std::regex_search(out, m, listening)) port = std::stoi(m[1]);
        }
        INFO(read_text(log));
        REQUIRE(port > 0);
    }
    ~Served() {
        ::kill(pid, SIGKILL);
        int st = 0;
        ::waitpid(pid, &st, 0);
    }
    // Resident memory, from /proc.
    double rss_mb() const {
        const std::string status = read_text(fs::path("/proc") / std::to_string(pid) / "status");
        const auto at = status.find("VmRSS:");
        REQUIRE(at != std::string::npos);
        return std::stod(status.substr(at + 6)) / 1024.0;
    }

    TempDir dir;
    fs::path db, log;
    std::string admin_key, read_key;
    pid_t pid = -1;
    int port = 0;
};

struct BodyAttempt {
    std::size_t announced = 0, sent = 0;
    int status = 0;
    double answer_ms = -1;
};

// Announces `announced` bytes of multipart body and sends them (zeros) until an answer comes,
// the server stops reading, or `limit_s` passes. Memory here stays one 1 MiB buffer.
BodyAttempt post_large_body(int port, const std::string& auth_line, std::size_t announced, double limit_s, bool expect_100 = false) {
    BodyAttempt a;
    a.announced = announced;
    const int fd = connect_loopback(port);
    REQUIRE(fd >= 0);
    const auto t0 = std::chrono::steady_clock::now();
    const std::string head = "POST /api/v1/runs HTTP/1.1\r\nHost: 127.0.0.1\r\n" + auth_line +
                             "Content-Type: multipart/form-data; boundary=xyz\r\nContent-Length: " + std::to_string(announced) +
                             "\r\n" + (expect_100 ? "Expect: 100-continue\r\n" : "") + "\r\n";
    REQUIRE(send_all(fd, head));
    const std::string zeros(1u << 20, '\0');
    std::string in;
    char buf[4096];
    const auto until = t0 + std::chrono::duration<double>(limit_s);
    bool can_send = !expect_100;
    while (std::chrono::steady_clock::now() < until && in.find("\r\n\r\n") == std::string::npos) {
        pollfd p{fd, static_cast<short>(POLLIN | (can_send && a.sent < announced ? POLLOUT : 0)), 0};
        if (::poll(&p, 1, 50) <= 0) continue;
        if (p.revents & POLLIN) {
            const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
            if (n <= 0) break;
            in.append(buf, static_cast<std::size_t>(n));
            continue;
        }
        if (p.revents & POLLOUT) {
            const ssize_t n = ::send(fd, zeros.data(), std::min(zeros.size(), announced - a.sent), MSG_NOSIGNAL | MSG_DONTWAIT);
            if (n < 0 && errno != EAGAIN) break;   // the server closed: read what it answered
            if (n > 0) a.sent += static_cast<std::size_t>(n);
        } else if (p.revents & (POLLERR | POLLHUP)) {
            break;
        }
    }
    // What arrived before a reset, if anything.
    if (in.find("\r\n\r\n") == std::string::npos) in += read_answer(fd, 200);
    if (status_of(in) != 0) a.answer_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    a.status = status_of(in);
    ::close(fd);
    return a;
}

struct Latency {
    double p50 = 0, p95 = 0, max = 0;
    int failed = 0;
};

Latency healthz_latency(int port, double for_s) {
    std::vector<double> ms;
    Latency l;
    const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(for_s);
    while (std::chrono::steady_clock::now() < until) {
        httplib::Client c("127.0.0.1", port);
        c.set_read_timeout(3, 0);
        c.set_connection_timeout(3, 0);
        const auto t0 = std::chrono::steady_clock::now();
        auto r = c.Get("/healthz");
        const double dt = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
        if (!r || r->status != 200) ++l.failed;
        ms.push_back(dt);
        std::this_thread::sleep_for(std::chrono::milliseconds(40));
    }
    std::sort(ms.begin(), ms.end());
    l.p50 = ms[ms.size() / 2];
    l.p95 = ms[std::min(ms.size() - 1, ms.size() * 95 / 100)];
    l.max = ms.back();
    return l;
}

// Opens `n` connections that each send a request line, then one header line every 2 s.
struct SlowClients {
    SlowClients(int port, int n) {
        for (int i = 0; i < n; ++i) {
            const int fd = connect_loopback(port);
            REQUIRE(fd >= 0);
            send_all(fd, "GET /api/v1/runs HTTP/1.1\r\nHost: 127.0.0.1\r\n");
            fds.push_back(fd);
        }
        dripper = std::thread([this] {
            for (int line = 0; !stop; ++line) {
                for (int fd : fds) send_all(fd, "X-Slow-" + std::to_string(line) + ": 1\r\n");
                for (int i = 0; i < 20 && !stop; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(100));
            }
        });
    }
    ~SlowClients() {
        stop = true;
        dripper.join();
        for (int fd : fds) ::close(fd);
    }
    // How many connections the server answered (status) or closed, waiting up to timeout_ms each.
    std::pair<int, int> answered_and_closed(int status, int timeout_ms) {
        int answered = 0, closed = 0;
        for (int fd : fds) {
            const std::string a = read_answer(fd, timeout_ms);
            if (status_of(a) == status) ++answered;
            char c;
            if (status_of(a) != 0 || ::recv(fd, &c, 1, MSG_DONTWAIT) == 0) ++closed;
        }
        return {answered, closed};
    }

    std::vector<int> fds;
    std::atomic<bool> stop{false};
    std::thread dripper;
};

}  // namespace

TEST_CASE("hostile: keyless POSTs announcing large bodies get 401 at once and the server does not buffer them") {
    Served s;
    // The service's fixed cost first (a request warms the thread pool and the store).
    REQUIRE(httplib::Client("127.0.0.1", s.port).Get("/healthz")->status == 200);
    const double rss_before = s.rss_mb();

    std::vector<BodyAttempt> attempts(12);
    {
        std::vector<std::thread> threads;
        for (int i = 0; i < 12; ++i)
            threads.emplace_back([&, i] {
                // 50 to 250 MB announced, under the 256 MiB body limit: the key is what is refused.
                const std::size_t announced = (50u + 200u * static_cast<std::size_t>(i) / 11u) * 1000u * 1000u;
                attempts[static_cast<std::size_t>(i)] = post_large_body(s.port, "", announced, 5.0);
            });
        for (auto& t : threads) t.join();
    }
    const double rss_after = s.rss_mb();
    double sent_mb = 0, worst_ms = 0;
    for (const auto& a : attempts) {
        std::printf("  keyless POST: %6.0f MB announced, %6.1f MB sent before the answer, HTTP %d after %.1f ms\n",
                    a.announced / 1e6, a.sent / 1e6, a.status, a.answer_ms);
        sent_mb += a.sent / 1e6;
        worst_ms = std::max(worst_ms, a.answer_ms);
    }
    std::printf("  server RSS: %.1f MB before, %.1f MB after 12 keyless POSTs (%.1f MB sent in all; slowest answer %.1f ms)\n",
                rss_before, rss_after, sent_mb, worst_ms);
    for (const auto& a : attempts) {
        REQUIRE(a.status == 401);
        REQUIRE(a.answer_ms < 2000);
    }
    REQUIRE(rss_after - rss_before < 64);

    // A key with too small a role is refused on the headers the same way, and a client that asks
    // "Expect: 100-continue" hears the 401 without sending a byte of its body.
    const BodyAttempt reader = post_large_body(s.port, "Authorization: Bearer " + s.read_key + "\r\n", 200'000'000, 5.0);
    REQUIRE(reader.status == 403);
    REQUIRE(reader.answer_ms < 2000);
    const BodyAttempt expect = post_large_body(s.port, "", 200'000'000, 5.0, true);
    REQUIRE(expect.status == 401);
    REQUIRE(expect.sent == 0);
    // Beyond the body limit, a keyed request is 413 before its body.
    const BodyAttempt big = post_large_body(s.port, "Authorization: Bearer " + s.admin_key + "\r\n", 300'000'000, 5.0);
    REQUIRE(big.status == 413);
    REQUIRE(big.answer_ms < 2000);
    // A body sent to a route that takes none, without a key, is not read either.
    const int fd = connect_loopback(s.port);
    REQUIRE(send_all(fd, "POST /api/v1/nowhere HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Length: 100000000\r\n\r\n"));
    REQUIRE(status_of(read_answer(fd, 2000)) == 404);
    ::close(fd);
    REQUIRE(s.rss_mb() - rss_before < 64);
}

TEST_CASE("hostile: 200 slow connections do not delay /healthz, and each is cut off at the header deadline") {
    Served s({"--header-timeout-s", "5"});
    REQUIRE(httplib::Client("127.0.0.1", s.port).Get("/healthz")->status == 200);
    const auto t0 = std::chrono::steady_clock::now();
    SlowClients slow(s.port, 200);
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    const Latency l = healthz_latency(s.port, 4.0);
    std::printf("  /healthz under 200 slow connections (a header line every 2 s): p50 %.2f ms, p95 %.2f ms, max %.2f ms, %d failed\n",
                l.p50, l.p95, l.max, l.failed);
    REQUIRE(l.failed == 0);
    REQUIRE(l.p95 < 100);
    // Still sending a line every 2 s, none has finished its headers: 408 at the 5 s deadline.
    const auto [answered, closed] = slow.answered_and_closed(408, 3000);
    const double cut_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::printf("  slow connections: %d of 200 answered 408 and closed within %.1f s of opening\n", answered, cut_s);
    REQUIRE(answered == 200);
    REQUIRE(closed == 200);
}

TEST_CASE("hostile: beyond the cap on waiting connections the longest waiting are closed and /healthz still answers") {
    Served s({"--max-waiting-connections", "100"});
    SlowClients slow(s.port, 200);
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    const Latency l = healthz_latency(s.port, 0.5);
    std::printf("  /healthz with 200 slow connections against a cap of 100: p50 %.2f ms, p95 %.2f ms, max %.2f ms, %d failed\n",
                l.p50, l.p95, l.max, l.failed);
    REQUIRE(l.failed == 0);
    // The first ones opened are the ones closed (without an answer: they never sent a request);
    // each /healthz connection, new, pushes out one more of the oldest.
    int closed_first = 0, closed_last = 0;
    for (int i = 0; i < 200; ++i) {
        char c;
        const ssize_t n = ::recv(slow.fds[static_cast<std::size_t>(i)], &c, 1, MSG_DONTWAIT);
        const bool closed = n == 0 || (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK);
        (i < 100 ? closed_first : closed_last) += closed ? 1 : 0;
    }
    std::printf("  closed by the server: %d of the first 100 opened, %d of the last 100\n", closed_first, closed_last);
    REQUIRE(closed_first == 100);
    REQUIRE(closed_last < 60);
}
