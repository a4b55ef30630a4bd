// The replay adapter (live/replay.hpp): one thread runs a poll() loop over the listening socket,
// the clients and the log's next line, which is sent when its shifted stamp falls due.
#include "live/replay.hpp"

#include "motion_io/readings.hpp"
#include "net.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <condition_variable>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <vector>

#include <fcntl.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

namespace cutload::live {
namespace {

using Clock = std::chrono::steady_clock;
using motion_io::ShdrLineKind;
constexpr std::int64_t kNsPerSec = 1'000'000'000;
// Between loop passes the stamps jump by at least this much, so a consumer sees one pass end
// before the next begins (the machine "moves" from the last position back to the first).
constexpr std::int64_t kPassGapNs = kNsPerSec;
constexpr std::size_t kMaxClientLine = 65536;   // clients only send PINGs
constexpr std::size_t kMaxSnapshotLine = 65536;

std::int64_t wall_now_ns() {
    return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
        .count();
}

// Shortest text that reads back as the same double.
std::string number(double v) { return fmt::format("{}", v); }

// Stamps on these lines pace the replay; asset lines carry the asset's own (often older) time.
bool paces(ShdrLineKind k) { return k == ShdrLineKind::Data || k == ShdrLineKind::Condition; }
bool has_stamp(ShdrLineKind k) {
    return k == ShdrLineKind::Data || k == ShdrLineKind::Condition || k == ShdrLineKind::Asset ||
           k == ShdrLineKind::Multiline;
}
bool is_sent(ShdrLineKind k) { return k != ShdrLineKind::Blank && k != ShdrLineKind::Command; }

}  // namespace

ShdrOutputKeys shdr_output_keys(const std::string& map_file) {
    ShdrOutputKeys k;
    if (map_file.empty()) {
        k.position = "path_pos";
        k.feed = "path_feedrate";
        k.spindle = "spindle_speed";
        k.block = "block";
        k.units = motion_io::shdr_unit_factors(motion_io::default_shdr_key_map());
        return k;
    }
    const motion_io::ShdrKeyMap m = motion_io::load_shdr_key_map(map_file);
    const auto first = [&](const std::vector<std::string>& list, const char* channel, bool required) {
        if (list.empty() && required)
            throw motion_io::IngestError(fmt::format("{}: key '{}': no key to write the channel under", map_file, channel));
        return list.empty() ? std::string() : list.front();
    };
    k.position = first(m.position, "position", false);
    if (k.position.empty()) {
        k.x = first(m.x, "x", true);
        k.y = first(m.y, "y", true);
        k.z = first(m.z, "z", true);
    }
    k.feed = first(m.feed, "feed", false);
    k.spindle = first(m.spindle, "spindle", false);
    k.block = first(m.block, "block", false);
    try {
        k.units = motion_io::shdr_unit_factors(m);
    } catch (const std::invalid_argument& e) {
        throw motion_io::IngestError(fmt::format("{}: {}", map_file, e.what()));
    }
    return k;
}

std::size_t write_csv_as_shdr(const std::string& csv_path, const motion_io::ReadOptions& opt, std::FILE* out) {
    using motion_io::LogReading;
    const ShdrOutputKeys keys = shdr_output_keys(opt.map_file);
    std::string line;
    std::int64_t line_ns = 0;
    std::size_t lines = 0;
    const auto flush = [&] {
        if (line.empty()) return;
        line += '\n';
        if (std::fwrite(line.data(), 1, line.size(), out) != line.size())
            throw std::runtime_error(fmt::format("cannot write the SHDR form of {}: {}", csv_path, std::strerror(errno)));
        line.clear();
        ++lines;
    };
    // The map names the keys the readings are written under, not the log's columns: the CSV is read
    // with its own header names (and the units given).
    motion_io::ReadOptions read = opt;
    read.map_file.clear();
    motion_io::read_csv_readings(csv_path, read, [&](const LogReading& r) {
        const std::int64_t ns = std::llround(r.t_s * 1e9);
        if (line.empty() || ns != line_ns) {
            flush();
            line = motion_io::format_iso_time(ns);
            line_ns = ns;
        }
        const double len = keys.units.length_mm;
        switch (r.channel) {
            case LogReading::Channel::Position:
                if (!keys.position.empty())
                    line += fmt::format("|{}|{} {} {}", keys.position, number(r.value[0] / len), number(r.value[1] / len),
                                        number(r.value[2] / len));
                else
                    line += fmt::format("|{}|{}|{}|{}|{}|{}", keys.x, number(r.value[0] / len), keys.y,
                                        number(r.value[1] / len), keys.z, number(r.value[2] / len));
                break;
            case LogReading::Channel::Feed:
                if (!keys.feed.empty()) line += fmt::format("|{}|{}", keys.feed, number(r.value[0] / keys.units.feed_mm_min));
                break;
            case LogReading::Channel::Spindle:
                if (!keys.spindle.empty())
                    line += fmt::format("|{}|{}", keys.spindle, number(r.value[0] / keys.units.spindle_rpm));
                break;
            case LogReading::Channel::Block:
                if (r.block.find('|') != std::string_view::npos)
                    throw motion_io::IngestError(fmt::format("{}:{}: block '{}' holds '|', which SHDR cannot carry",
                                                             csv_path, r.line, r.block));
                if (!keys.block.empty()) line += fmt::format("|{}|{}", keys.block, r.block);
                break;
        }
    });
    flush();
    return lines;
}

class ReplayAdapter::Engine {
public:
    explicit Engine(ReplayOptions opt) : opt_(std::move(opt)) {
        if (!(opt_.speed > 0) || !std::isfinite(opt_.speed))
            throw std::invalid_argument(fmt::format("speed: must be a positive number, got {}", opt_.speed));
        if (opt_.heartbeat.count() <= 0) throw std::invalid_argument("heartbeat: must be at least 1 ms");
        if (opt_.max_pause_s && !(*opt_.max_pause_s >= 0))
            throw std::invalid_argument("max pause: must be 0 s or more");
        format_ = opt_.read.format == motion_io::Format::Auto ? motion_io::detect_log_format(opt_.log) : opt_.read.format;
        if (format_ == motion_io::Format::Shdr &&
            (!opt_.read.map_file.empty() || opt_.read.length_unit || opt_.read.feed_unit))
            throw std::invalid_argument(fmt::format("{}: an SHDR log is replayed as recorded; a map file (--map) and "
                                                    "units (--units, --feed-units) apply to CSV logs only", opt_.log));
        open_log();
        validate();
        listen_ = net::listen_tcp(opt_.host, opt_.port, port_);
        if (::pipe2(wake_, O_CLOEXEC | O_NONBLOCK) != 0)
            throw std::runtime_error(fmt::format("pipe: {}", std::strerror(errno)));
        thread_ = std::thread([this] { run(); });
    }

    ~Engine() {
        stop();
        ::close(wake_[0]);
        ::close(wake_[1]);
    }

    void stop() {
        std::lock_guard<std::mutex> guard(stop_mu_);
        if (!thread_.joinable()) return;
        const char c = 'x';
        (void)!::write(wake_[1], &c, 1);
        thread_.join();
        clients_.clear();
        listen_.reset();
    }

    int port() const { return port_; }
    std::size_t lines() const { return lines_per_pass_; }
    double duration_s() const { return duration_s_; }
    motion_io::Format format() const { return format_; }

    bool wait_finished(std::chrono::milliseconds timeout) const {
        std::unique_lock<std::mutex> lock(mu_);
        return cv_.wait_for(lock, timeout, [this] { return stats_.finished; });
    }

    ReplayStats stats() const {
        std::lock_guard<std::mutex> lock(mu_);
        return stats_;
    }

private:
    struct Client {
        net::Fd fd;
        std::string in, out;
        bool closed = false;
    };

    // ---- the log ----
    void open_log() {
        if (format_ == motion_io::Format::Shdr) {
            in_.open(opt_.log, std::ios::binary);
            if (!in_) throw motion_io::IngestError(fmt::format("{}: cannot open file", opt_.log));
            return;
        }
        // A CSV log is written out as SHDR once (bounded memory, any length), then replayed as
        // an SHDR log is. The file is unlinked at once; the open stream keeps it readable.
        std::string path = (std::filesystem::temp_directory_path() / "cutload_replay_XXXXXX").string();
        const int fd = ::mkstemp(path.data());
        if (fd < 0) throw std::runtime_error(fmt::format("cannot create a temporary file: {}", std::strerror(errno)));
        std::FILE* f = ::fdopen(fd, "wb");
        try {
            write_csv_as_shdr(opt_.log, opt_.read, f);
        } catch (...) {
            std::fclose(f);
            std::filesystem::remove(path);
            throw;
        }
        const bool ok = std::fclose(f) == 0;
        in_.open(path, std::ios::binary);
        std::filesystem::remove(path);
        if (!ok || !in_) throw std::runtime_error(fmt::format("cannot write the SHDR form of {}", opt_.log));
        source_name_ = opt_.log + " (as SHDR)";
    }

    // One pass over the lines: time stamps of data lines valid (as the SHDR reader demands),
    // the first pacing stamp, the playing time and the number of lines.
    void validate() {
        if (source_name_.empty()) source_name_ = opt_.log;
        motion_io::ShdrLineTokenizer tokens;
        std::string line;
        std::size_t line_no = 0;
        bool have_first = false, have_data = false;
        std::int64_t clock = 0;
        double total_ns = 0;
        while (std::getline(in_, line)) {
            ++line_no;
            const ShdrLineKind kind = tokens.next(line);
            if (!is_sent(kind)) continue;
            ++lines_per_pass_;
            if (!paces(kind)) continue;
            const auto stamp = motion_io::parse_iso_time(tokens.fields()[0]);
            if (!stamp) {
                if (kind == ShdrLineKind::Condition) continue;   // sent as it is
                throw motion_io::IngestError(fmt::format(
                    "{}:{}: '{}' is not an ISO 8601 time stamp (expected e.g. 2022-08-08T13:51:34.7167146Z)", opt_.log,
                    line_no, tokens.fields()[0]));
            }
            const std::int64_t ns = stamp->nanos();
            have_data = have_data || kind == ShdrLineKind::Data;
            if (!have_first) {
                first_ns_ = clock = ns;
                have_first = true;
            }
            total_ns += static_cast<double>(step_ns(ns - clock));
            clock = ns;
        }
        if (!have_data) throw motion_io::IngestError(fmt::format("{}: no data lines ('timestamp|key|value') to replay", opt_.log));
        duration_s_ = total_ns / 1e9;
        rewind();
    }

    void rewind() {
        in_.clear();
        in_.seekg(0);
        tokens_.reset();
    }

    // How long the log waits before a line `dt` after the previous one (before the speed-up).
    std::int64_t step_ns(std::int64_t dt) const {
        if (dt <= 0) return 0;   // a jump back (a new recording, reordered lines) is sent at once
        if (opt_.max_pause_s) return std::min<std::int64_t>(dt, std::llround(*opt_.max_pause_s * 1e9));
        return dt;
    }

    void start_pass() {
        rewind();
        // Rounded to whole microseconds so that the shifted stamps keep the log's own digits.
        const std::int64_t now_ns = wall_now_ns() / 1000 * 1000;
        std::int64_t start = now_ns;
        if (sent_any_) start = std::max(start, max_sent_ns_ + kPassGapNs);
        offset_ns_ = start - first_ns_;
        log_clock_ns_ = first_ns_;
        // The pause between passes is delivered like any other (divided by the speed), so at
        // speed 1 the stamps stay with the wall clock pass after pass.
        due_ = Clock::now() + std::chrono::nanoseconds(std::llround(static_cast<double>(start - now_ns) / opt_.speed));
        have_pending_ = false;
        advance();
    }

    // Reads the next line to send into pending_ and sets when it is due.
    void advance() {
        std::string line;
        while (std::getline(in_, line)) {
            const ShdrLineKind kind = tokens_.next(line);
            if (!is_sent(kind)) continue;
            if (!has_stamp(kind)) {
                pending_ = line;   // multi-line bodies and malformed lines go as they are
                if (!pending_.empty() && pending_.back() == '\r') pending_.pop_back();
                have_pending_ = true;
                return;
            }
            const auto& f = tokens_.fields();
            const auto stamp = motion_io::parse_iso_time(f[0]);
            if (!stamp) {
                pending_ = line;
                if (!pending_.empty() && pending_.back() == '\r') pending_.pop_back();
                have_pending_ = true;
                return;
            }
            const std::int64_t ns = stamp->nanos();
            const std::int64_t shifted = ns + offset_ns_;
            const std::string_view stamp_text = f[0];
            const auto at = stamp_text.find('@');
            pending_ = motion_io::format_iso_time(shifted);
            if (at != std::string_view::npos) pending_ += stamp_text.substr(at);
            for (std::size_t i = 1; i < f.size(); ++i) {
                pending_ += '|';
                pending_ += f[i];
            }
            if (paces(kind)) {
                const double wait_ns = static_cast<double>(step_ns(ns - log_clock_ns_)) / opt_.speed;
                due_ += std::chrono::nanoseconds(std::llround(wait_ns));
                log_clock_ns_ = ns;
                pending_stamp_ns_ = shifted;
            }
            if (kind == ShdrLineKind::Data) {
                pending_pairs_.clear();
                for (std::size_t i = 1; i + 1 < f.size(); i += 2) pending_pairs_.emplace_back(f[i], f[i + 1]);
            }
            have_pending_ = true;
            pending_is_data_ = kind == ShdrLineKind::Data;
            return;
        }
        // End of a pass.
        have_pending_ = false;
        std::lock_guard<std::mutex> lock(mu_);
        ++stats_.passes_done;
        if (opt_.loop) {
            loop_again_ = true;
        } else {
            stats_.finished = true;
            cv_.notify_all();
        }
    }

    void send_pending() {
        broadcast(pending_);
        if (pending_is_data_) {
            for (auto& [k, v] : pending_pairs_) state_[k] = v;
            pending_is_data_ = false;
        }
        last_sent_ns_ = pending_stamp_ns_;
        max_sent_ns_ = sent_any_ ? std::max(max_sent_ns_, pending_stamp_ns_) : pending_stamp_ns_;
        sent_any_ = true;
        std::lock_guard<std::mutex> lock(mu_);
        ++stats_.lines_sent;
    }

    // ---- clients ----
    void broadcast(const std::string& line) {
        for (Client& c : clients_) queue(c, line);
    }

    void queue(Client& c, std::string_view line) {
        if (c.closed) return;
        c.out.append(line);
        c.out += '\n';
        if (c.out.size() > opt_.max_client_backlog_bytes) {
            drop(c, true);
            return;
        }
        flush(c);
    }

    void flush(Client& c) {
        while (!c.closed && !c.out.empty()) {
            const ssize_t n = ::send(c.fd.get(), c.out.data(), c.out.size(), MSG_NOSIGNAL);
            if (n < 0) {
                if (errno == EAGAIN || errno == EWOULDBLOCK) return;
                if (errno == EINTR) continue;
                drop(c, false);
                return;
            }
            c.out.erase(0, static_cast<std::size_t>(n));
        }
    }

    void drop(Client& c, bool too_slow) {
        c.closed = true;
        c.fd.reset();
        std::lock_guard<std::mutex> lock(mu_);
        if (too_slow) ++stats_.clients_dropped;
    }

    void read_client(Client& c) {
        char buf[4096];
        const ssize_t n = ::recv(c.fd.get(), buf, sizeof buf, 0);
        if (n == 0 || (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR)) {
            drop(c, false);
            return;
        }
        if (n < 0) return;
        c.in.append(buf, static_cast<std::size_t>(n));
        std::size_t eol;
        while ((eol = c.in.find('\n')) != std::string::npos) {
            std::string_view l(c.in.data(), eol);
            while (!l.empty() && (l.back() == '\r' || l.back() == ' ')) l.remove_suffix(1);
            if (l == "* PING") {
                queue(c, fmt::format("* PONG {}", opt_.heartbeat.count()));
                std::lock_guard<std::mutex> lock(mu_);
                ++stats_.pings_answered;
            }
            c.in.erase(0, eol + 1);
        }
        if (c.in.size() > kMaxClientLine) drop(c, false);
    }

    void accept_clients() {
        while (true) {
            const int fd = ::accept4(listen_.get(), nullptr, nullptr, SOCK_NONBLOCK | SOCK_CLOEXEC);
            if (fd < 0) return;
            Client c;
            c.fd.reset(fd);
            clients_.push_back(std::move(c));
            {
                std::lock_guard<std::mutex> lock(mu_);
                ++stats_.clients_accepted;
            }
            if (!started_) {
                started_ = true;
                {
                    std::lock_guard<std::mutex> lock(mu_);
                    stats_.started = true;
                }
                start_pass();
            } else {
                send_state(clients_.back());
            }
        }
    }

    // What an adapter sends a new connection: the latest value of every key, stamped with the
    // time of the last line sent.
    void send_state(Client& c) {
        if (state_.empty()) return;
        const std::string stamp = motion_io::format_iso_time(last_sent_ns_);
        std::string line = stamp;
        for (const auto& [k, v] : state_) {
            if (line.size() > stamp.size() && line.size() + k.size() + v.size() + 2 > kMaxSnapshotLine) {
                queue(c, line);
                line = stamp;
            }
            line += '|' + k + '|' + v;
        }
        queue(c, line);
    }

    // ---- the loop ----
    void run() {
        std::vector<pollfd> fds;
        while (true) {
            fds.clear();
            fds.push_back({wake_[0], POLLIN, 0});
            fds.push_back({listen_.get(), POLLIN, 0});
            for (const Client& c : clients_)
                fds.push_back({c.fd.get(), static_cast<short>(POLLIN | (c.out.empty() ? 0 : POLLOUT)), 0});
            timespec ts{};
            timespec* timeout = nullptr;
            if (have_pending_) {
                const auto left = std::max<std::int64_t>(
                    0, std::chrono::duration_cast<std::chrono::nanoseconds>(due_ - Clock::now()).count());
                ts.tv_sec = static_cast<time_t>(left / kNsPerSec);
                ts.tv_nsec = static_cast<long>(left % kNsPerSec);
                timeout = &ts;
            }
            const int n = ::ppoll(fds.data(), fds.size(), timeout, nullptr);
            if (n < 0 && errno != EINTR) return;
            if (n > 0) {
                if (fds[0].revents) return;   // stop()
                if (fds[1].revents & POLLIN) accept_clients();
                for (std::size_t i = 2; i < fds.size(); ++i) {
                    Client& c = clients_[i - 2];
                    if (fds[i].revents & (POLLIN | POLLHUP | POLLERR)) read_client(c);
                    if (!c.closed && (fds[i].revents & POLLOUT)) flush(c);
                }
            }
            // Everything due goes out now; a late loop catches up at once rather than drifting.
            while (have_pending_ && Clock::now() >= due_) {
                send_pending();
                advance();
                if (loop_again_) {
                    loop_again_ = false;
                    start_pass();
                }
            }
            const auto gone = std::remove_if(clients_.begin(), clients_.end(), [](const Client& c) { return c.closed; });
            clients_.erase(gone, clients_.end());
            std::lock_guard<std::mutex> lock(mu_);
            stats_.clients_now = clients_.size();
        }
    }

    const ReplayOptions opt_;
    motion_io::Format format_ = motion_io::Format::Shdr;
    std::string source_name_;
    std::ifstream in_;
    motion_io::ShdrLineTokenizer tokens_;
    std::size_t lines_per_pass_ = 0;
    double duration_s_ = 0;
    std::int64_t first_ns_ = 0;

    net::Fd listen_;
    int port_ = 0;
    int wake_[2] = {-1, -1};
    std::thread thread_;
    std::mutex stop_mu_;
    std::vector<Client> clients_;

    // Playback (the loop thread's own).
    bool started_ = false, have_pending_ = false, pending_is_data_ = false, loop_again_ = false, sent_any_ = false;
    std::string pending_;
    std::vector<std::pair<std::string, std::string>> pending_pairs_;
    std::int64_t pending_stamp_ns_ = 0, last_sent_ns_ = 0, max_sent_ns_ = 0;
    std::int64_t offset_ns_ = 0, log_clock_ns_ = 0;
    Clock::time_point due_{};
    std::map<std::string, std::string> state_;

    mutable std::mutex mu_;
    mutable std::condition_variable cv_;
    ReplayStats stats_;
};

ReplayAdapter::ReplayAdapter(ReplayOptions opt) : engine_(std::make_unique<Engine>(std::move(opt))) {}
ReplayAdapter::~ReplayAdapter() = default;
int ReplayAdapter::port() const { return engine_->port(); }
void ReplayAdapter::stop() { engine_->stop(); }
bool ReplayAdapter::wait_finished(std::chrono::milliseconds timeout) const { return engine_->wait_finished(timeout); }
ReplayStats ReplayAdapter::stats() const { return engine_->stats(); }
std::size_t ReplayAdapter::log_lines() const { return engine_->lines(); }
double ReplayAdapter::log_duration_s() const { return engine_->duration_s(); }
motion_io::Format ReplayAdapter::log_format() const { return engine_->format(); }

}  // namespace cutload::live
