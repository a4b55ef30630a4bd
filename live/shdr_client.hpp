// The SHDR source: a TCP client of an MTConnect adapter (the protocol an agent speaks to its
// adapters). As in the MTConnect agent, the connection (ShdrClient: connect, heartbeat,
// reconnect, lines) lives apart from the parsing (ShdrSource: motion_io's SHDR line tokenizer
// turns lines into observations).
#pragma once

#include "live/live.hpp"
#include "motion_io/shdr.hpp"

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

namespace cutload::live {

struct ShdrOptions {
    std::string host = "127.0.0.1";
    int port = 7878;   // the adapters' customary port
    Backoff backoff;
    // One connection attempt (all addresses of the host) may hold next() this long; a cancel
    // still ends it within 50 ms.
    std::chrono::milliseconds connect_timeout{2000};
    // With no heartbeat agreed (an adapter that never answers '* PING'), the connection counts as
    // dead after this long without data (the MTConnect agent's legacy timeout is 600 s too).
    std::chrono::milliseconds legacy_timeout{600000};
    // Heartbeat to use once the adapter answers '* PONG', instead of the period it announces.
    std::optional<std::chrono::milliseconds> heartbeat;
    std::size_t max_line_bytes = 1 << 20;   // a longer line is skipped (Warning)
};

struct LineBatch {
    std::vector<std::string> lines;     // without '\n' and trailing white space; blank lines and PONGs left out
    std::vector<SourceEvent> events;    // after this batch's lines
    void clear() {
        lines.clear();
        events.clear();
    }
};

// The connection: yields the adapter's lines. On connecting it sends '* PING'; the adapter's
// '* PONG <ms>' sets the heartbeat: a '* PING' every <ms>, and the connection is dead after
// 2 x <ms> with nothing received. A lost connection is retried with exponential backoff; the
// first connection after a loss reports a Gap.
class ShdrClient {
public:
    explicit ShdrClient(ShdrOptions opt);
    ~ShdrClient();
    ShdrClient(const ShdrClient&) = delete;
    ShdrClient& operator=(const ShdrClient&) = delete;

    // As Source::next, with lines instead of observations.
    void next(LineBatch& out, std::chrono::milliseconds wait, const std::atomic<bool>& cancel);

    bool connected() const;
    // The heartbeat in force on this connection (none before a PONG, or from a legacy adapter).
    std::optional<std::chrono::milliseconds> heartbeat() const { return heartbeat_; }
    std::uint64_t pings_sent() const { return pings_sent_; }
    std::uint64_t pongs_received() const { return pongs_received_; }
    const ShdrOptions& options() const { return opt_; }

private:
    using Clock = std::chrono::steady_clock;
    void try_connect(LineBatch& out, const std::atomic<bool>& cancel);
    void read_available(LineBatch& out);
    void take_line(std::string_view line, LineBatch& out);
    void send_ping(LineBatch& out);
    void lose(LineBatch& out, const std::string& why);
    void warn(LineBatch& out, const std::string& what);

    ShdrOptions opt_;
    int fd_ = -1;
    unsigned failures_ = 0;            // since the last connection that delivered data
    Clock::time_point next_attempt_{};
    bool had_connection_ = false;      // a later connection reports a Gap
    Clock::time_point last_rx_{};
    WallClock::time_point last_rx_wall_{};
    std::optional<std::chrono::milliseconds> heartbeat_;
    Clock::time_point next_ping_{};
    std::string inbuf_;
    bool skipping_long_line_ = false;
    unsigned warnings_ = 0;            // on this connection
    std::uint64_t pings_sent_ = 0, pongs_received_ = 0;
};

// ShdrClient + motion_io::ShdrLineTokenizer: data lines become observations (one per key/value
// pair, stamped with the line's time stamp). Conditions, assets, multi-line bodies and protocol
// lines are skipped, as the file reader skips them; a line without a valid time stamp is a Warning.
class ShdrSource final : public Source {
public:
    explicit ShdrSource(ShdrOptions opt);
    void next(Batch& out, std::chrono::milliseconds wait, const std::atomic<bool>& cancel) override;
    std::string describe() const override;
    ShdrClient& client() { return client_; }

private:
    void warn(Batch& out, const std::string& what);

    ShdrClient client_;
    motion_io::ShdrLineTokenizer tokens_;
    LineBatch lines_;
    std::int64_t last_stamp_ns_ = 0;
    unsigned warnings_ = 0;
};

}  // namespace cutload::live
