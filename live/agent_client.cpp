// MTConnect agent client (live/agent_client.hpp). All HTTP runs on the source's own thread, so
// next() never blocks on the network and honours a cancel at once; the thread hands over
// batches through a short queue.
#include "live/agent_client.hpp"

#include "events.hpp"

#include <fmt/format.h>
#include <httplib.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <condition_variable>
#include <deque>
#include <mutex>
#include <optional>
#include <thread>

namespace cutload::live {
namespace {

using Clock = std::chrono::steady_clock;
constexpr std::size_t kMaxQueuedBatches = 64;
constexpr std::size_t kObservationsPerBatch = 4096;

std::string percent_encode(const std::string& s) {
    std::string out;
    for (unsigned char c : s) {
        if (std::isalnum(c) || c == '-' || c == '.' || c == '_' || c == '~') out += static_cast<char>(c);
        else out += fmt::format("%{:02X}", c);
    }
    return out;
}

bool looks_like_xml(std::string_view body) {
    const auto first = body.find_first_not_of(" \t\r\n");
    return first != std::string_view::npos && body[first] == '<';
}

// Reads the parts of a multipart stream (one MTConnectStreams document each):
//   --BOUNDARY\r\nContent-type: text/xml\r\nContent-length: N\r\n\r\n<N bytes>\r\n--BOUNDARY ...
// A part without Content-length ends at the next boundary.
class MultipartReader {
public:
    MultipartReader(std::string boundary, std::size_t max_part) : marker_("--" + std::move(boundary)), max_part_(max_part) {}

    // False (and error()) for a stream that cannot be read on.
    bool feed(std::string_view data) {
        buf_.append(data);
        while (true) {
            if (!in_body_) {
                const auto b = buf_.find(marker_);
                if (b == std::string::npos) {
                    // Keep a possible partial marker only; anything else before a boundary is preamble.
                    if (buf_.size() > marker_.size()) buf_.erase(0, buf_.size() - marker_.size());
                    return true;
                }
                std::size_t end = buf_.find("\r\n\r\n", b);
                std::size_t sep = 4;
                if (const auto lf = buf_.find("\n\n", b); lf != std::string::npos && (end == std::string::npos || lf < end))
                    end = lf, sep = 2;
                if (end == std::string::npos) {
                    if (buf_.size() - b > 16384) return fail("part headers longer than 16 KiB");
                    return true;
                }
                length_ = content_length(std::string_view(buf_).substr(b + marker_.size(), end - b - marker_.size()));
                if (length_ && *length_ > max_part_) return fail(fmt::format("a part of {} bytes (limit {})", *length_, max_part_));
                buf_.erase(0, end + sep);
                in_body_ = true;
            }
            if (length_) {
                if (buf_.size() < *length_) return true;
                parts_.emplace_back(buf_, 0, *length_);
                buf_.erase(0, *length_);
            } else {
                const auto next = buf_.find(marker_);
                if (next == std::string::npos) {
                    if (buf_.size() > max_part_) return fail(fmt::format("a part over {} bytes without Content-length", max_part_));
                    return true;
                }
                parts_.emplace_back(buf_, 0, next);
                buf_.erase(0, next);
            }
            in_body_ = false;
        }
    }
    std::optional<std::string> pop() {
        if (parts_.empty()) return std::nullopt;
        std::string p = std::move(parts_.front());
        parts_.pop_front();
        return p;
    }
    const std::string& error() const { return error_; }

private:
    bool fail(std::string why) {
        error_ = std::move(why);
        return false;
    }
    static std::optional<std::size_t> content_length(std::string_view headers) {
        std::string lower(headers);
        std::transform(lower.begin(), lower.end(), lower.begin(), [](unsigned char c) { return std::tolower(c); });
        const auto at = lower.find("content-length:");
        if (at == std::string::npos) return std::nullopt;
        std::size_t i = at + 15;
        while (i < lower.size() && lower[i] == ' ') ++i;
        std::size_t v = 0;
        const auto [end, ec] = std::from_chars(lower.data() + i, lower.data() + lower.size(), v);
        if (ec != std::errc() || end == lower.data() + i) return std::nullopt;
        return v;
    }

    std::string marker_;
    std::size_t max_part_;
    std::string buf_;
    bool in_body_ = false;
    std::optional<std::size_t> length_;
    std::deque<std::string> parts_;
    std::string error_;
};

std::string boundary_of(const std::string& content_type) {
    const auto at = content_type.find("boundary=");
    if (at == std::string::npos) return {};
    std::string b = content_type.substr(at + 9);
    if (const auto semi = b.find(';'); semi != std::string::npos) b.erase(semi);
    if (b.size() >= 2 && b.front() == '"' && b.back() == '"') b = b.substr(1, b.size() - 2);
    return b;
}

}  // namespace

class AgentSource::Worker {
public:
    Worker(AgentOptions opt, std::string origin, std::string prefix)
        : opt_(std::move(opt)), origin_(std::move(origin)), prefix_(std::move(prefix)),
          http_(origin_), stream_http_(origin_) {
        const auto timeout = opt_.request_timeout;
        http_.set_connection_timeout(timeout);
        http_.set_read_timeout(timeout);
        http_.set_keep_alive(true);
        // Small requests and answers: without this, Nagle and delayed ACKs cost ~40 ms a poll.
        http_.set_tcp_nodelay(true);
        stream_http_.set_tcp_nodelay(true);
        stream_http_.set_connection_timeout(timeout);
        stream_http_.set_read_timeout(2 * opt_.heartbeat);
        thread_ = std::thread([this] { run(); });
    }

    ~Worker() {
        {
            std::lock_guard<std::mutex> lock(mu_);
            stop_ = true;
        }
        cv_.notify_all();
        http_.stop();
        stream_http_.stop();
        thread_.join();
    }

    void pop(Batch& out, std::chrono::milliseconds wait, const std::atomic<bool>& cancel) {
        out.clear();
        const auto deadline = Clock::now() + wait;
        std::unique_lock<std::mutex> lock(mu_);
        while (queue_.empty()) {
            const auto now = Clock::now();
            if (cancel.load() || now >= deadline) return;
            cv_.wait_until(lock, std::min(deadline, now + std::chrono::milliseconds(50)));
        }
        out = std::move(queue_.front());
        queue_.pop_front();
        cv_.notify_all();
    }

    std::vector<DataItemInfo> items() const {
        std::lock_guard<std::mutex> lock(mu_);
        return items_;
    }
    std::uint64_t instance_id() const {
        std::lock_guard<std::mutex> lock(mu_);
        return instance_;
    }
    std::uint64_t next_sequence() const {
        std::lock_guard<std::mutex> lock(mu_);
        return next_seq_;
    }

private:
    // What handling a document led to.
    enum class Outcome { Continue, Resynchronised, Failed };

    struct Response {
        bool ok = false;        // a document came back (any status)
        int status = 0;
        std::string body;
        std::string error;      // why not
    };

    // ---- thread ----
    void run() {
        while (!stopping()) {
            if (!connected_) {
                if (!sleep_until(next_attempt_)) return;
                synchronise();
                continue;
            }
            if (opt_.mode == AgentOptions::Mode::Poll) {
                const bool caught_up = poll_once();
                if (caught_up && connected_ && !sleep_until(Clock::now() + opt_.poll_interval)) return;
            } else {
                stream_once();
            }
        }
    }

    bool stopping() const {
        std::lock_guard<std::mutex> lock(mu_);
        return stop_;
    }

    // False when stopped while sleeping.
    bool sleep_until(Clock::time_point t) {
        std::unique_lock<std::mutex> lock(mu_);
        cv_.wait_until(lock, t, [this] { return stop_; });
        return !stop_;
    }

    void push(Batch&& b) {
        if (b.empty()) return;
        std::unique_lock<std::mutex> lock(mu_);
        cv_.wait(lock, [this] { return stop_ || queue_.size() < kMaxQueuedBatches; });
        if (stop_) return;
        queue_.push_back(std::move(b));
        cv_.notify_all();
    }

    void push_events(std::vector<SourceEvent> events) {
        Batch b;
        b.events = std::move(events);
        push(std::move(b));
    }

    void push_observations(std::vector<Observation>& obs) {
        for (std::size_t i = 0; i < obs.size(); i += kObservationsPerBatch) {
            Batch b;
            const std::size_t end = std::min(obs.size(), i + kObservationsPerBatch);
            b.observations.assign(std::make_move_iterator(obs.begin() + static_cast<std::ptrdiff_t>(i)),
                                  std::make_move_iterator(obs.begin() + static_cast<std::ptrdiff_t>(end)));
            push(std::move(b));
        }
        if (!obs.empty()) {
            last_stamp_ns_ = obs.back().stamp_ns;
            last_data_wall_ = WallClock::now();
        }
    }

    void warn(const std::string& what) {
        if (auto e = limited_warning(warnings_, what)) push_events({std::move(*e)});
    }

    void failure(const std::string& why) {
        ++failures_;
        const auto retry = opt_.backoff.delay(failures_);
        next_attempt_ = Clock::now() + retry;
        SourceEvent e = make_event(connected_ ? EventKind::Disconnected : EventKind::ConnectFailed,
                              fmt::format("{}: {}; retrying in {} ms", origin_ + prefix_, why, retry.count()));
        e.retry_in = retry;
        connected_ = false;
        push_events({std::move(e)});
    }

    // ---- HTTP ----
    Response get(httplib::Client& cli, const std::string& path) {
        Response r;
        bool too_big = false;
        auto res = cli.Get(
            path, httplib::Headers{{"Accept", "application/xml"}},
            [&](const httplib::Response& head) {
                r.status = head.status;
                return true;
            },
            [&](const char* data, std::size_t len) {
                r.body.append(data, len);
                too_big = r.body.size() > opt_.max_document_bytes;
                return !too_big && !stopping();
            });
        if (too_big) {
            r.error = fmt::format("GET {}: document over {} bytes", path, opt_.max_document_bytes);
            return r;
        }
        if (!res) {
            r.error = fmt::format("GET {}: {}", path, httplib::to_string(res.error()));
            return r;
        }
        if (!looks_like_xml(r.body)) {
            r.error = fmt::format("GET {}: HTTP {} without an MTConnect document", path, r.status);
            return r;
        }
        r.ok = true;
        return r;
    }

    std::string device_path(const char* request) const {
        if (device_name_.empty())
            return opt_.device.empty() ? fmt::format("{}/{}", prefix_, request)
                                       : fmt::format("{}/{}/{}", prefix_, percent_encode(opt_.device), request);
        return fmt::format("{}/{}/{}", prefix_, percent_encode(device_name_), request);
    }

    std::string sample_path() const {
        std::string p = fmt::format("{}?from={}&count={}", device_path("sample"), next_seq_, opt_.count);
        if (opt_.mode == AgentOptions::Mode::Stream)
            p += fmt::format("&interval={}&heartbeat={}", opt_.interval.count(), opt_.heartbeat.count());
        return p;
    }

    bool probe() {
        const Response r = get(http_, device_path("probe"));
        if (!r.ok) {
            failure(r.error);
            return false;
        }
        try {
            ProbeDocument doc = parse_probe(r.body, opt_.device);
            std::map<std::string, std::string> keys;
            for (const DataItemInfo& item : doc.items) keys[item.id] = item.key();
            std::lock_guard<std::mutex> lock(mu_);
            items_ = std::move(doc.items);
            keys_ = std::move(keys);
            device_name_ = doc.device_name;
        } catch (const SourceError& e) {
            failure(e.what());
            return false;
        }
        need_probe_ = false;
        return true;
    }

    // GET /current and decide where to go on from: the first time, after a failure, after
    // OUT_OF_RANGE (`out_of_range`), or after a changed instanceId seen in a sample.
    void synchronise(bool out_of_range = false, bool restarted = false) {
        if (restarted) need_probe_ = true;
        if (need_probe_ && !probe()) return;
        Response r = get(http_, device_path("current"));
        if (!r.ok) {
            failure(r.error);
            return;
        }
        StreamsDocument doc;
        try {
            doc = parse_streams(r.body, keys_, device_name_);
            if (!doc.is_error && synced_ && !restarted && doc.instance_id != instance_) {
                restarted = true;
                if (!probe()) return;
                doc = parse_streams(r.body, keys_, device_name_);
            }
        } catch (const SourceError& e) {
            failure(fmt::format("current: {}", e.what()));
            return;
        }
        if (doc.is_error) {
            failure(fmt::format("current: {}: {}", doc.errors.empty() ? "error" : doc.errors.front().code,
                                doc.errors.empty() ? "" : doc.errors.front().message));
            return;
        }
        std::vector<SourceEvent> events;
        const double gap_s = std::chrono::duration<double>(WallClock::now() - last_data_wall_).count();
        const bool behind = synced_ && !restarted && (out_of_range || next_seq_ < doc.first_sequence);
        if (restarted) {
            events.push_back(make_event(EventKind::Restarted, fmt::format("agent restarted: instanceId {} -> {}; "
                                                                     "probed again", instance_, doc.instance_id)));
            SourceEvent g = make_event(EventKind::Gap, fmt::format("observations after sequence {} of the old instance and "
                                                              "before sequence {} of the new one not received",
                                                              next_seq_ == 0 ? 0 : next_seq_ - 1, doc.next_sequence));
            g.gap_s = gap_s;
            g.last_stamp_ns = last_stamp_ns_;
            events.push_back(std::move(g));
        } else if (behind) {
            SourceEvent g = make_event(EventKind::Gap, fmt::format("sequences {} to {} no longer held by the agent (first "
                                                              "held: {}); resynchronised from /current",
                                                              next_seq_, doc.next_sequence - 1, doc.first_sequence));
            g.gap_s = gap_s;
            g.last_stamp_ns = last_stamp_ns_;
            g.lost_from_sequence = next_seq_;
            g.lost_to_sequence = doc.next_sequence;
            events.push_back(std::move(g));
        }
        const bool take_snapshot = !synced_ || restarted || behind;
        if (!connected_ || !events.empty())
            events.push_back(make_event(EventKind::Connected,
                                   take_snapshot ? fmt::format("synchronised with {} (device {}, instanceId {}) at "
                                                               "sequence {}", origin_ + prefix_, device_name_,
                                                               doc.instance_id, doc.next_sequence)
                                                 : fmt::format("reconnected to {}; resuming at sequence {}",
                                                               origin_ + prefix_, next_seq_)));
        connected_ = true;
        failures_ = 0;
        warnings_ = 0;
        {
            std::lock_guard<std::mutex> lock(mu_);
            instance_ = doc.instance_id;
            if (take_snapshot) next_seq_ = doc.next_sequence;
        }
        synced_ = true;
        push_events(std::move(events));
        for (const std::string& w : doc.warnings) warn(w);
        if (take_snapshot) push_observations(doc.observations);
    }

    // A sample document (polled, streamed, or an error instead of one).
    Outcome handle(const std::string& xml) {
        StreamsDocument doc;
        try {
            doc = parse_streams(xml, keys_, device_name_);
        } catch (const SourceError& e) {
            failure(fmt::format("sample: {}", e.what()));
            return Outcome::Failed;
        }
        if (doc.is_error) {
            if (doc.has_error("OUT_OF_RANGE")) {
                synchronise(true);
                return connected_ ? Outcome::Resynchronised : Outcome::Failed;
            }
            failure(fmt::format("sample: {}: {}", doc.errors.empty() ? "error" : doc.errors.front().code,
                                doc.errors.empty() ? "" : doc.errors.front().message));
            return Outcome::Failed;
        }
        if (doc.instance_id != instance_) {
            synchronise(false, true);
            return connected_ ? Outcome::Resynchronised : Outcome::Failed;
        }
        std::vector<Observation> fresh;
        for (Observation& o : doc.observations)
            if (o.sequence >= next_seq_) fresh.push_back(std::move(o));   // a repeated document adds nothing
        for (const std::string& w : doc.warnings) warn(w);
        {
            std::lock_guard<std::mutex> lock(mu_);
            next_seq_ = std::max(next_seq_, doc.next_sequence);
        }
        push_observations(fresh);
        // An empty heartbeat document proves the agent alive too.
        last_data_wall_ = WallClock::now();
        caught_up_ = doc.next_sequence > doc.last_sequence;
        return Outcome::Continue;
    }

    bool poll_once() {
        const Response r = get(http_, sample_path());
        if (!r.ok) {
            failure(r.error);
            return false;
        }
        return handle(r.body) == Outcome::Continue && caught_up_;
    }

    void stream_once() {
        const std::string path = sample_path();
        std::optional<MultipartReader> parts;
        std::string plain;   // a response that is not multipart: an error document
        std::string why;     // set when we end the stream
        bool resynchronised = false;
        auto res = stream_http_.Get(
            path, httplib::Headers{{"Accept", "application/xml"}},
            [&](const httplib::Response& head) {
                const std::string ct = head.get_header_value("Content-Type");
                if (ct.find("multipart") != std::string::npos && !boundary_of(ct).empty())
                    parts.emplace(boundary_of(ct), opt_.max_document_bytes);
                return true;
            },
            [&](const char* data, std::size_t len) {
                if (stopping()) return false;
                if (!parts) {
                    plain.append(data, len);
                    if (plain.size() > opt_.max_document_bytes) {
                        why = fmt::format("document over {} bytes", opt_.max_document_bytes);
                        return false;
                    }
                    return true;
                }
                if (!parts->feed(std::string_view(data, len))) {
                    why = fmt::format("unreadable stream: {}", parts->error());
                    return false;
                }
                while (auto doc = parts->pop()) {
                    const Outcome o = handle(*doc);
                    if (o == Outcome::Resynchronised) resynchronised = true;
                    if (o != Outcome::Continue) return false;   // a new stream from the new next sequence
                }
                return true;
            });
        if (stopping() || resynchronised || !connected_) return;   // stopped, or handled (failure recorded)
        if (!parts && !plain.empty() && why.empty()) {
            // An error document (OUT_OF_RANGE before the stream began), or an agent that answers
            // with one document: then this degrades to polling.
            if (handle(plain) == Outcome::Continue && caught_up_) sleep_until(Clock::now() + opt_.poll_interval);
            return;
        }
        if (!why.empty()) failure(why);
        else if (!res && res.error() == httplib::Error::Read)
            failure(fmt::format("stream stalled: nothing received for {} ms (twice the heartbeat)",
                                (2 * opt_.heartbeat).count()));
        else if (!res) failure(fmt::format("GET {}: {}", path, httplib::to_string(res.error())));
        else failure("the agent ended the stream");
    }

    const AgentOptions opt_;
    const std::string origin_, prefix_;
    httplib::Client http_, stream_http_;
    std::thread thread_;

    mutable std::mutex mu_;
    std::condition_variable cv_;
    bool stop_ = false;
    std::deque<Batch> queue_;
    // Under mu_ (read by the accessors); written by the thread only.
    std::vector<DataItemInfo> items_;
    std::uint64_t instance_ = 0, next_seq_ = 0;
    // The thread's own.
    std::map<std::string, std::string> keys_;
    std::string device_name_;
    bool need_probe_ = true, synced_ = false, connected_ = false, caught_up_ = false;
    unsigned failures_ = 0, warnings_ = 0;
    Clock::time_point next_attempt_{};
    WallClock::time_point last_data_wall_ = WallClock::now();
    std::int64_t last_stamp_ns_ = 0;
};

AgentSource::AgentSource(AgentOptions opt) {
    const auto scheme = opt.base_url.find("://");
    if (scheme == std::string::npos || (opt.base_url.compare(0, scheme, "http") != 0 &&
                                        opt.base_url.compare(0, scheme, "https") != 0))
        throw SourceError(fmt::format("agent URL '{}': expected http://HOST[:PORT][/PREFIX]", opt.base_url));
    const auto slash = opt.base_url.find('/', scheme + 3);
    std::string origin = opt.base_url.substr(0, slash);
    std::string prefix = slash == std::string::npos ? "" : opt.base_url.substr(slash);
    while (!prefix.empty() && prefix.back() == '/') prefix.pop_back();
    if (origin.size() <= scheme + 3) throw SourceError(fmt::format("agent URL '{}': no host", opt.base_url));
    if (opt.count == 0) throw SourceError("agent count: must be at least 1");
    if (opt.heartbeat.count() <= 0) throw SourceError("agent heartbeat: must be at least 1 ms");
    describe_ = opt.device.empty() ? origin + prefix : origin + prefix + "/" + opt.device;
    worker_ = std::make_unique<Worker>(std::move(opt), std::move(origin), std::move(prefix));
}

AgentSource::~AgentSource() = default;

void AgentSource::next(Batch& out, std::chrono::milliseconds wait, const std::atomic<bool>& cancel) {
    worker_->pop(out, wait, cancel);
}

std::string AgentSource::describe() const { return describe_; }
std::vector<DataItemInfo> AgentSource::data_items() const { return worker_->items(); }
std::uint64_t AgentSource::instance_id() const { return worker_->instance_id(); }
std::uint64_t AgentSource::next_sequence() const { return worker_->next_sequence(); }

}  // namespace cutload::live
