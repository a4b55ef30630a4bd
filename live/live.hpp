// Public interface of live: where a live run's data comes from. A source connects to the
// machine (an SHDR adapter, or an MTConnect agent over HTTP) and hands out what arrives as
// (time stamp, key, value) observations in small batches, with the connection's state changes
// and gaps as events. Both sources yield the same observations, so one key map
// (motion_io::ShdrKeyMap) applies to both. See docs/live.md.
//
// Driving a source: one worker thread owns it and calls next() in a loop; any thread may set the
// cancel flag. A source is not thread-safe otherwise.
//
//     std::atomic<bool> cancel{false};
//     auto src = live::open_source("shdr://10.0.0.5:7878");
//     live::Batch batch;
//     while (!cancel) {
//         src->next(batch, std::chrono::milliseconds(200), cancel);
//         for (const auto& o : batch.observations) ...;   // in arrival order
//         for (const auto& e : batch.events) ...;         // after this batch's observations
//     }
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace cutload::live {

using WallClock = std::chrono::system_clock;

// One value of one data item as the source stamped it.
struct Observation {
    std::int64_t stamp_ns = 0;   // source's time stamp, ns since 1970-01-01T00:00:00Z (UTC)
    std::string key;             // SHDR key, or the agent data item's name (its id when it has none)
    std::string value;           // as sent; "UNAVAILABLE" is kept (the consumer holds the last value)
    std::uint64_t sequence = 0;  // agent: the observation's sequence number; SHDR: 0
};

enum class EventKind {
    Connected,      // a connection (SHDR) or a synchronised agent session is up
    Disconnected,   // it was up and is lost; message says why, retry_in when the next attempt is
    ConnectFailed,  // an attempt failed while not connected; retry_in as above
    Gap,            // observations were lost (see the Gap fields)
    Restarted,      // the agent's instanceId changed: it restarted, its sequence numbers start over
    Warning,        // malformed input that was skipped (the first 20 per connection, then a summary)
};

const char* to_string(EventKind kind);

struct SourceEvent {
    EventKind kind = EventKind::Warning;
    WallClock::time_point at;      // when the source noticed it
    std::string message;           // one line, names what and why
    std::chrono::milliseconds retry_in{0};   // Disconnected, ConnectFailed
    // Gap: the wall-clock time without data (from the last byte received to data flowing again),
    // the source stamp of the last observation before it (0 if none), and for an agent the
    // sequence numbers that were never received, [lost_from_sequence, lost_to_sequence).
    double gap_s = 0;
    std::int64_t last_stamp_ns = 0;
    std::uint64_t lost_from_sequence = 0, lost_to_sequence = 0;
};

struct Batch {
    std::vector<Observation> observations;   // in arrival order
    std::vector<SourceEvent> events;         // all after this batch's observations
    void clear() {
        observations.clear();
        events.clear();
    }
    bool empty() const { return observations.empty() && events.empty(); }
};

// Exponential reconnect backoff: the first retry after `initial`, each failed attempt doubles the
// delay up to `max`. A connection that delivers data resets it.
struct Backoff {
    std::chrono::milliseconds initial{500};
    std::chrono::milliseconds max{30000};
    std::chrono::milliseconds delay(unsigned failures) const;   // failures >= 1
};

class Source {
public:
    virtual ~Source() = default;
    // Clears `out`, then waits up to `wait` for data and fills it with what arrived. Returns as
    // soon as anything arrived (a batch holds what one read brought, at most a few thousand
    // observations), after an event, when `wait` elapsed (empty batch), or when `cancel` was set
    // (checked at least every 50 ms). A connection attempt may hold it longer, up to the
    // source's connect timeout (SHDR; 2 s by default). Network trouble never throws: it arrives
    // as events while the source keeps reconnecting. Call it again well within a heartbeat: the
    // SHDR source sends its pings from inside next().
    virtual void next(Batch& out, std::chrono::milliseconds wait, const std::atomic<bool>& cancel) = 0;
    // "shdr://host:port" or "http://host:port/device".
    virtual std::string describe() const = 0;
};

// A bad source address or option: says which and why.
class SourceError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

// "HOST:PORT" ("[v6 address]:PORT" too); without a port `default_port`, or an error when it is
// negative. Throws SourceError naming the text and what is wrong.
struct HostPort {
    std::string host;
    int port = 0;
};
HostPort parse_host_port(const std::string& text, int default_port = -1);

// shdr://HOST[:PORT] (default port 7878), or http(s)://HOST[:PORT][/PREFIX]/DEVICE for an agent
// (the last path segment names the device; http://HOST:PORT/ alone means the agent's only device).
// Default options for everything else; throws SourceError for a malformed address.
std::unique_ptr<Source> open_source(const std::string& url);

}  // namespace cutload::live
