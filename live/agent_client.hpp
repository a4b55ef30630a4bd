// The MTConnect agent source: an HTTP client of an agent's REST interface.
//   /DEVICE/probe     data item ids -> names (the observation keys) and units
//   /DEVICE/current   instanceId, nextSequence and the latest value of every data item
//   /DEVICE/sample?from=N&count=M[&interval=I&heartbeat=H]
//                     the observations from sequence N on; with interval the agent keeps the
//                     response open and streams one document per interval (multipart)
// It follows nextSequence; when the agent no longer holds the sequence it asked for
// (OUT_OF_RANGE) it marks the gap and resynchronises from /current; when the agent's instanceId
// changes (a restart) it probes again and resynchronises. See docs/live.md.
#pragma once

#include "live/agent_xml.hpp"
#include "live/live.hpp"

#include <memory>
#include <string>
#include <vector>

namespace cutload::live {

struct AgentOptions {
    std::string base_url = "http://127.0.0.1:5000";   // scheme://host:port[/prefix]; agents customarily use 5000
    std::string device;                               // name or uuid; empty: the agent's only device
    enum class Mode { Stream, Poll };
    Mode mode = Mode::Stream;
    unsigned count = 1000;                            // observations per document at most
    std::chrono::milliseconds interval{50};           // Stream: the agent sends a document at most this often
    std::chrono::milliseconds heartbeat{1000};        // Stream: an empty document after this long without data;
                                                      // the stream is dead after twice as long without a byte
    std::chrono::milliseconds poll_interval{250};     // Poll: pause between requests once caught up
    std::chrono::milliseconds request_timeout{5000};  // connect, and read for probe / current / polled sample
    std::size_t max_document_bytes = 16u << 20;       // a larger document is a protocol error
    Backoff backoff;
};

class AgentSource final : public Source {
public:
    // Starts its own HTTP thread at once (next() only hands over what it collected; a cancel
    // stops the waiting in next(), the destructor stops the thread). Throws SourceError for a
    // malformed base URL.
    explicit AgentSource(AgentOptions opt);
    ~AgentSource() override;
    AgentSource(const AgentSource&) = delete;
    AgentSource& operator=(const AgentSource&) = delete;

    void next(Batch& out, std::chrono::milliseconds wait, const std::atomic<bool>& cancel) override;
    std::string describe() const override;

    // The device's data items as last probed (units for the key map), empty before the first probe.
    std::vector<DataItemInfo> data_items() const;
    std::uint64_t instance_id() const;
    std::uint64_t next_sequence() const;   // the sequence the next sample request asks for

private:
    class Worker;
    std::unique_ptr<Worker> worker_;
    std::string describe_;
};

}  // namespace cutload::live
