// SHDR adapter client (live/shdr_client.hpp): connection and heartbeat, then lines to observations.
#include "live/shdr_client.hpp"

#include "events.hpp"
#include "net.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cstring>
#include <thread>

#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

namespace cutload::live {
namespace {

constexpr std::chrono::milliseconds kCancelSlice{50};
// The MTConnect agent ignores a PONG period of 30 min or more as bogus; so do we.
constexpr std::chrono::milliseconds kMaxHeartbeat{30 * 60 * 1000};

}  // namespace

ShdrClient::ShdrClient(ShdrOptions opt) : opt_(std::move(opt)) {}

ShdrClient::~ShdrClient() {
    if (fd_ >= 0) ::close(fd_);
}

bool ShdrClient::connected() const { return fd_ >= 0; }

void ShdrClient::warn(LineBatch& out, const std::string& what) {
    if (auto e = limited_warning(warnings_, what)) out.events.push_back(std::move(*e));
}

void ShdrClient::lose(LineBatch& out, const std::string& why) {
    ::close(fd_);
    fd_ = -1;
    heartbeat_.reset();
    inbuf_.clear();
    skipping_long_line_ = false;
    ++failures_;   // a drop counts as a failure: an adapter that accepts and hangs up backs off too
    const auto retry = opt_.backoff.delay(failures_);
    next_attempt_ = Clock::now() + retry;
    SourceEvent e = make_event(EventKind::Disconnected,
                          fmt::format("{}:{}: {}; reconnecting in {} ms", opt_.host, opt_.port, why, retry.count()));
    e.retry_in = retry;
    out.events.push_back(std::move(e));
}

void ShdrClient::try_connect(LineBatch& out, const std::atomic<bool>& cancel) {
    std::string error;
    net::Fd fd = net::connect_tcp(opt_.host, opt_.port, opt_.connect_timeout, cancel, error);
    if (!fd) {
        if (cancel.load()) return;
        ++failures_;
        const auto retry = opt_.backoff.delay(failures_);
        next_attempt_ = Clock::now() + retry;
        SourceEvent e = make_event(EventKind::ConnectFailed, fmt::format("cannot connect to {}:{}: {}; retrying in {} ms",
                                                                    opt_.host, opt_.port, error, retry.count()));
        e.retry_in = retry;
        out.events.push_back(std::move(e));
        return;
    }
    fd_ = fd.release();
    warnings_ = 0;
    const auto now = Clock::now();
    const WallClock::time_point wall_now = WallClock::now();
    out.events.push_back(make_event(EventKind::Connected, fmt::format("connected to {}:{}", opt_.host, opt_.port)));
    if (had_connection_) {
        // An adapter keeps no history: what it sent while we were away is lost.
        SourceEvent g = make_event(EventKind::Gap, fmt::format("no connection to {}:{} for {:.3f} s", opt_.host, opt_.port,
                                                          std::chrono::duration<double>(wall_now - last_rx_wall_).count()));
        g.gap_s = std::chrono::duration<double>(wall_now - last_rx_wall_).count();
        out.events.push_back(std::move(g));
    }
    had_connection_ = true;
    last_rx_ = now;
    last_rx_wall_ = wall_now;
    send_ping(out);
}

void ShdrClient::send_ping(LineBatch& out) {
    static constexpr char kPing[] = "* PING\n";
    const ssize_t n = ::send(fd_, kPing, sizeof kPing - 1, MSG_NOSIGNAL);
    // Eight bytes on an idle socket do not block; a full send buffer means the peer is stuck.
    if (n != static_cast<ssize_t>(sizeof kPing - 1)) {
        lose(out, n < 0 ? fmt::format("cannot send PING: {}", std::strerror(errno)) : "cannot send PING: send buffer full");
        return;
    }
    ++pings_sent_;
    if (heartbeat_) next_ping_ = Clock::now() + *heartbeat_;
}

void ShdrClient::take_line(std::string_view line, LineBatch& out) {
    while (!line.empty() && std::isspace(static_cast<unsigned char>(line.back()))) line.remove_suffix(1);
    if (line.empty()) return;
    if (line.rfind("* PONG", 0) == 0) {
        ++pongs_received_;
        if (heartbeat_) return;   // heartbeats already running
        std::string_view rest = line.substr(6);
        while (!rest.empty() && rest.front() == ' ') rest.remove_prefix(1);
        long long ms = 0;
        const auto [end, ec] = std::from_chars(rest.data(), rest.data() + rest.size(), ms);
        std::chrono::milliseconds period{ms};
        if (opt_.heartbeat) period = *opt_.heartbeat;
        else if (ec != std::errc() || rest.empty()) {
            warn(out, fmt::format("'{}': PONG without a period in ms; no heartbeat on this connection", line));
            return;
        }
        if (period.count() <= 0 || period >= kMaxHeartbeat) {
            warn(out, fmt::format("'{}': heartbeat period out of range (1 ms .. 30 min); ignored", line));
            return;
        }
        heartbeat_ = period;
        next_ping_ = Clock::now() + period;
        return;
    }
    out.lines.emplace_back(line);
}

void ShdrClient::read_available(LineBatch& out) {
    char buf[65536];
    const ssize_t n = ::recv(fd_, buf, sizeof buf, 0);
    if (n == 0) {
        lose(out, "the adapter closed the connection");
        return;
    }
    if (n < 0) {
        if (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR) return;
        lose(out, fmt::format("read failed: {}", std::strerror(errno)));
        return;
    }
    last_rx_ = Clock::now();
    last_rx_wall_ = WallClock::now();
    failures_ = 0;
    std::string_view data(buf, static_cast<std::size_t>(n));
    while (!data.empty()) {
        const std::size_t eol = data.find('\n');
        if (eol == std::string_view::npos) {
            if (!skipping_long_line_) inbuf_.append(data);
            if (inbuf_.size() > opt_.max_line_bytes) {
                warn(out, fmt::format("a line longer than {} bytes; skipped", opt_.max_line_bytes));
                inbuf_.clear();
                skipping_long_line_ = true;
            }
            return;
        }
        if (skipping_long_line_) {
            skipping_long_line_ = false;
        } else if (inbuf_.empty()) {
            if (eol > opt_.max_line_bytes) warn(out, fmt::format("a line longer than {} bytes; skipped", opt_.max_line_bytes));
            else take_line(data.substr(0, eol), out);
        } else {
            inbuf_.append(data.substr(0, eol));
            if (inbuf_.size() > opt_.max_line_bytes) warn(out, fmt::format("a line longer than {} bytes; skipped", opt_.max_line_bytes));
            else take_line(inbuf_, out);
            inbuf_.clear();
        }
        data.remove_prefix(eol + 1);
    }
}

void ShdrClient::next(LineBatch& out, std::chrono::milliseconds wait, const std::atomic<bool>& cancel) {
    out.clear();
    const auto deadline = Clock::now() + wait;
    while (!cancel.load()) {
        auto now = Clock::now();
        if (fd_ < 0) {
            if (now < next_attempt_) {
                if (now >= deadline) return;
                std::this_thread::sleep_until(std::min({next_attempt_, deadline, now + kCancelSlice}));
                continue;
            }
            try_connect(out, cancel);
            return;   // Connected or ConnectFailed: hand the event over at once
        }
        const auto dead_after = heartbeat_ ? 2 * *heartbeat_ : opt_.legacy_timeout;
        auto until = std::min({deadline, last_rx_ + dead_after, now + kCancelSlice});
        if (heartbeat_) until = std::min(until, next_ping_);
        const auto timeout_ms = std::max<long long>(
            0, std::chrono::duration_cast<std::chrono::milliseconds>(until - now).count() + 1);
        pollfd p{fd_, POLLIN, 0};
        const int ready = ::poll(&p, 1, static_cast<int>(timeout_ms));
        if (ready < 0 && errno != EINTR) {
            lose(out, fmt::format("poll failed: {}", std::strerror(errno)));
            return;
        }
        if (ready > 0) read_available(out);
        if (fd_ < 0) return;   // lost while reading
        now = Clock::now();
        if (heartbeat_ && now >= next_ping_) {
            send_ping(out);
            if (fd_ < 0) return;
        }
        if (now - last_rx_ > dead_after) {
            lose(out, heartbeat_ ? fmt::format("nothing received for {} ms (twice the {} ms heartbeat)",
                                               dead_after.count(), heartbeat_->count())
                                 : fmt::format("nothing received for {} ms (no heartbeat agreed)", dead_after.count()));
            return;
        }
        if (!out.lines.empty() || !out.events.empty() || now >= deadline) return;
    }
}

// ---- ShdrSource ----

ShdrSource::ShdrSource(ShdrOptions opt) : client_(std::move(opt)) {}

std::string ShdrSource::describe() const {
    return fmt::format("shdr://{}:{}", client_.options().host, client_.options().port);
}

void ShdrSource::warn(Batch& out, const std::string& what) {
    if (auto e = limited_warning(warnings_, what)) out.events.push_back(std::move(*e));
}

void ShdrSource::next(Batch& out, std::chrono::milliseconds wait, const std::atomic<bool>& cancel) {
    out.clear();
    client_.next(lines_, wait, cancel);
    for (const std::string& line : lines_.lines) {
        const motion_io::ShdrLineKind kind = tokens_.next(line);
        if (kind == motion_io::ShdrLineKind::Short) {
            warn(out, fmt::format("'{:.80}': not 'timestamp|key|value'; skipped", line));
            continue;
        }
        if (kind != motion_io::ShdrLineKind::Data) continue;
        const auto& f = tokens_.fields();
        const auto stamp = motion_io::parse_iso_time(f[0]);
        if (!stamp) {
            warn(out, fmt::format("'{:.80}': '{}' is not an ISO 8601 time stamp; line skipped", line, f[0]));
            continue;
        }
        const std::int64_t ns = stamp->nanos();
        for (std::size_t i = 1; i + 1 < f.size(); i += 2)
            out.observations.push_back({ns, std::string(f[i]), std::string(f[i + 1]), 0});
        if (tokens_.odd_fields()) warn(out, fmt::format("'{:.80}': key '{}' without a value; ignored", line, f.back()));
        last_stamp_ns_ = ns;
    }
    for (SourceEvent& e : lines_.events) {
        if (e.kind == EventKind::Connected || e.kind == EventKind::Disconnected) {
            tokens_.reset();   // a multi-line body cut by the drop never closes
            warnings_ = 0;
        }
        if (e.kind == EventKind::Gap) e.last_stamp_ns = last_stamp_ns_;
        out.events.push_back(std::move(e));
    }
}

}  // namespace cutload::live
