// A tiny MTConnect agent for the tests: /probe, /current and /sample (polled, or streamed as
// multipart with interval) over a ring buffer of observations the test publishes. It can lose
// sequences (as a buffer overrun does, forcing OUT_OF_RANGE), restart with a new instanceId,
// hold sample requests, and stop and start listening on the same port. Documents follow the
// MTConnect 2.x schema as the reference C++ agent writes them (samples and events grouped by
// component, not in sequence order; OUT_OF_RANGE as HTTP 400 with an MTConnectError).
#pragma once

#include "motion_io/shdr.hpp"

#include <catch2/catch.hpp>
#include <fmt/format.h>
#include <httplib.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <map>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace cutload::live::test {

class AgentFixture {
public:
    struct Item {
        std::string id, name, category, type, units;
    };
    struct Published {
        std::uint64_t sequence;
        std::string item_id;
        std::int64_t stamp_ns;
        std::string value;
    };

    AgentFixture(std::vector<Item> items, std::string device, std::size_t buffer_size = 4096)
        : items_(std::move(items)), device_(std::move(device)), buffer_size_(buffer_size) {
        start_listening(0);
    }
    ~AgentFixture() { stop_listening(); }

    int port() const { return port_; }
    std::string url() const { return fmt::format("http://127.0.0.1:{}", port_); }

    // Appends an observation with the next sequence number.
    void publish(const std::string& item_id, std::int64_t stamp_ns, const std::string& value) {
        {
            std::lock_guard<std::mutex> lock(mu_);
            buffer_.push_back({next_seq_++, item_id, stamp_ns, value});
            latest_[item_id] = buffer_.back();
            while (buffer_.size() > buffer_size_) buffer_.pop_front();
        }
        cv_.notify_all();
    }
    // Forgets every observation up to and including `seq`, as a buffer overrun would.
    void discard_through(std::uint64_t seq) {
        std::lock_guard<std::mutex> lock(mu_);
        while (!buffer_.empty() && buffer_.front().sequence <= seq) buffer_.pop_front();
        first_override_ = std::max(first_override_, seq + 1);
    }
    // A new process: a new instanceId, sequences from 1, an empty buffer and no current values.
    void restart() {
        {
            std::lock_guard<std::mutex> lock(mu_);
            ++instance_;
            next_seq_ = 1;
            first_override_ = 0;
            buffer_.clear();
            latest_.clear();
        }
        cv_.notify_all();   // open streams end: the old process is gone
    }
    // Sample requests wait (at most 10 s) while held.
    void hold_samples(bool hold) {
        {
            std::lock_guard<std::mutex> lock(mu_);
            hold_ = hold;
        }
        cv_.notify_all();
    }
    std::uint64_t next_sequence() const {
        std::lock_guard<std::mutex> lock(mu_);
        return next_seq_;
    }
    std::uint64_t instance_id() const {
        std::lock_guard<std::mutex> lock(mu_);
        return instance_;
    }
    std::size_t requests(const std::string& kind) const {
        std::lock_guard<std::mutex> lock(mu_);
        const auto it = requests_.find(kind);
        return it == requests_.end() ? 0 : it->second;
    }
    std::size_t held_requests() const {
        std::lock_guard<std::mutex> lock(mu_);
        return held_now_;
    }

    void stop_listening() {
        if (server_) server_->stop();   // no new connections from here on
        {
            std::lock_guard<std::mutex> lock(mu_);
            stopping_ = true;
        }
        cv_.notify_all();
        if (thread_.joinable()) thread_.join();
        server_.reset();
    }
    // Listens again on the same port (0 the first time: any).
    void start_listening(int port) {
        {
            std::lock_guard<std::mutex> lock(mu_);
            stopping_ = false;
        }
        server_ = std::make_unique<httplib::Server>();
        server_->set_tcp_nodelay(true);
        routes(*server_);
        if (port == 0) {
            port_ = server_->bind_to_any_port("127.0.0.1");
        } else {
            bool bound = false;
            for (int i = 0; i < 50 && !bound; ++i) {
                bound = server_->bind_to_port("127.0.0.1", port);
                if (!bound) std::this_thread::sleep_for(std::chrono::milliseconds(20));
            }
            REQUIRE(bound);
        }
        REQUIRE(port_ > 0);
        thread_ = std::thread([this] { server_->listen_after_bind(); });
        for (int i = 0; i < 200 && !server_->is_running(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }

    // The observations of one sample document from `from` (at most `count`), as the agent's header.
    struct Window {
        std::uint64_t first, next_out, last;
        std::vector<Published> obs;
    };

private:
    std::uint64_t first_locked() const {
        const std::uint64_t first = buffer_.empty() ? next_seq_ : buffer_.front().sequence;
        return std::max(first, std::min(first_override_, next_seq_));
    }

    std::string element_name(const std::string& type) const {
        std::string out;
        bool upper = true;
        for (char c : type) {
            if (c == '_') {
                upper = true;
                continue;
            }
            out += upper ? c : static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
            upper = false;
        }
        return out;
    }

    const Item* item(const std::string& id) const {
        for (const Item& i : items_)
            if (i.id == id) return &i;
        return nullptr;
    }

    std::string header(std::uint64_t first, std::uint64_t next, std::uint64_t last) const {
        return fmt::format(R"(<Header creationTime="2026-01-01T00:00:00Z" sender="fixture" instanceId="{}" version="2.2.0" )"
                           R"(bufferSize="{}" firstSequence="{}" lastSequence="{}" nextSequence="{}"/>)",
                           instance_, buffer_size_, first, last, next);
    }

    std::string streams_doc(const std::vector<Published>& obs, std::uint64_t first, std::uint64_t next,
                            std::uint64_t last) const {
        // Grouped as an agent groups them: by component (one here), samples before events.
        std::string samples, events;
        for (const Published& p : obs) {
            const Item* it = item(p.item_id);
            const std::string el = element_name(it->type);
            const std::string xml = fmt::format(R"(<{} dataItemId="{}" name="{}" sequence="{}" timestamp="{}">{}</{}>)", el,
                                                it->id, it->name, p.sequence, motion_io::format_iso_time(p.stamp_ns),
                                                p.value, el);
            (it->category == "SAMPLE" ? samples : events) += xml;
        }
        return fmt::format(R"(<?xml version="1.0" encoding="UTF-8"?>)"
                           R"(<MTConnectStreams xmlns="urn:mtconnect.org:MTConnectStreams:2.2">{}<Streams>)"
                           R"(<DeviceStream name="{}" uuid="{}-uuid"><ComponentStream component="Path" componentId="p1">)"
                           R"({}{}<Condition><Normal dataItemId="p1cond" timestamp="2026-01-01T00:00:00Z" sequence="1" type="SYSTEM"/></Condition>)"
                           R"(</ComponentStream></DeviceStream></Streams></MTConnectStreams>)",
                           header(first, next, last), device_, device_,
                           samples.empty() ? "" : "<Samples>" + samples + "</Samples>",
                           events.empty() ? "" : "<Events>" + events + "</Events>");
    }

    std::string out_of_range_doc(std::uint64_t from, std::uint64_t first, std::uint64_t next) const {
        return fmt::format(R"(<?xml version="1.0" encoding="UTF-8"?>)"
                           R"(<MTConnectError xmlns="urn:mtconnect.org:MTConnectError:2.2">)"
                           R"(<Header creationTime="2026-01-01T00:00:00Z" sender="fixture" instanceId="{}" version="2.2.0" bufferSize="{}"/>)"
                           R"(<Errors><OutOfRange errorCode="OUT_OF_RANGE"><ErrorMessage>'from' must be greater than {}</ErrorMessage>)"
                           R"(<QueryParameter name="from"><Value>{}</Value><Minimum>{}</Minimum><Maximum>{}</Maximum></QueryParameter>)"
                           R"(</OutOfRange></Errors></MTConnectError>)",
                           instance_, buffer_size_, first - 1, from, first, next);
    }

    // Under mu_. nullopt: `from` is out of range.
    std::optional<Window> window(std::uint64_t from, std::uint64_t count) const {
        const std::uint64_t first = first_locked();
        if (from < first || from > next_seq_) return std::nullopt;
        Window w{first, from, next_seq_ - 1, {}};
        for (const Published& p : buffer_) {
            if (p.sequence < from) continue;
            if (w.obs.size() >= count) break;
            w.obs.push_back(p);
        }
        w.next_out = w.obs.empty() ? from : w.obs.back().sequence + 1;
        return w;
    }

    void count_request(const std::string& kind) {
        std::lock_guard<std::mutex> lock(mu_);
        ++requests_[kind];
    }

    void wait_unheld(std::unique_lock<std::mutex>& lock) {
        ++held_now_;
        cv_.wait_for(lock, std::chrono::seconds(10), [this] { return !hold_ || stopping_; });
        --held_now_;
    }

    void routes(httplib::Server& s) {
        const std::string dev = "/" + device_;
        s.Get(dev + "/probe", [this](const httplib::Request&, httplib::Response& res) {
            count_request("probe");
            std::string items;
            for (const Item& i : items_)
                items += fmt::format(R"(<DataItem category="{}" id="{}" name="{}" type="{}"{}/>)", i.category, i.id, i.name,
                                     i.type, i.units.empty() ? "" : fmt::format(R"( units="{}")", i.units));
            std::lock_guard<std::mutex> lock(mu_);
            res.set_content(fmt::format(R"(<?xml version="1.0" encoding="UTF-8"?>)"
                                        R"(<MTConnectDevices xmlns="urn:mtconnect.org:MTConnectDevices:2.2">)"
                                        R"(<Header creationTime="2026-01-01T00:00:00Z" sender="fixture" instanceId="{}" version="2.2.0" bufferSize="{}" assetBufferSize="8" assetCount="0"/>)"
                                        R"(<Devices><Agent id="agent" name="Agent" uuid="agent-uuid"><DataItems><DataItem category="EVENT" id="agent_avail" type="AVAILABILITY"/></DataItems></Agent>)"
                                        R"(<Device id="dev" name="{}" uuid="{}-uuid"><Components><Path id="p1"><DataItems>{})"
                                        R"(<DataItem category="CONDITION" id="p1cond" type="SYSTEM"/></DataItems></Path></Components></Device></Devices></MTConnectDevices>)",
                                        instance_, buffer_size_, device_, device_, items),
                            "application/xml");
        });
        s.Get(dev + "/current", [this](const httplib::Request&, httplib::Response& res) {
            count_request("current");
            std::lock_guard<std::mutex> lock(mu_);
            std::vector<Published> obs;
            for (const auto& [id, p] : latest_) obs.push_back(p);
            res.set_content(streams_doc(obs, first_locked(), next_seq_, next_seq_ - 1), "application/xml");
        });
        s.Get(dev + "/sample", [this](const httplib::Request& req, httplib::Response& res) {
            count_request("sample");
            const std::uint64_t count = req.has_param("count") ? std::stoull(req.get_param_value("count")) : 100;
            std::uint64_t from = 0;
            {
                std::unique_lock<std::mutex> lock(mu_);
                wait_unheld(lock);
                from = req.has_param("from") ? std::stoull(req.get_param_value("from")) : first_locked();
                if (!req.has_param("interval")) {
                    const auto w = window(from, count);
                    if (!w) {
                        res.status = 400;
                        res.set_content(out_of_range_doc(from, first_locked(), next_seq_), "application/xml");
                        return;
                    }
                    res.set_content(streams_doc(w->obs, w->first, w->next_out, w->last), "application/xml");
                    return;
                }
                if (!window(from, count)) {
                    res.status = 400;
                    res.set_content(out_of_range_doc(from, first_locked(), next_seq_), "application/xml");
                    return;
                }
            }
            count_request("stream");
            const auto interval = std::chrono::milliseconds(std::stoll(req.get_param_value("interval")));
            const auto heartbeat = std::chrono::milliseconds(
                req.has_param("heartbeat") ? std::stoll(req.get_param_value("heartbeat")) : 10000);
            auto state = std::make_shared<StreamState>();
            state->from = from;
            state->instance = instance_id();
            res.set_chunked_content_provider(
                "multipart/mixed;boundary=a5e4f3c2-fixture",
                [this, state, count, interval, heartbeat](std::size_t, httplib::DataSink& sink) {
                    std::unique_lock<std::mutex> lock(mu_);
                    if (state->sent_any) {
                        const auto earliest = state->last_sent + interval;
                        cv_.wait_until(lock, earliest, [this] { return stopping_; });
                    }
                    // Wait for news, a heartbeat, a restart or the end.
                    cv_.wait_for(lock, heartbeat, [&] {
                        return stopping_ || hold_ || instance_ != state->instance || next_seq_ > state->from ||
                               first_locked() > state->from;
                    });
                    if (hold_) wait_unheld(lock);
                    if (stopping_ || instance_ != state->instance) {
                        sink.done();   // the process is gone: the stream just ends
                        return true;
                    }
                    const auto w = window(state->from, count);
                    std::string body;
                    bool end = false;
                    if (!w) {
                        body = out_of_range_doc(state->from, first_locked(), next_seq_);
                        end = true;   // as the reference agent: the error, then the stream closes
                    } else {
                        body = streams_doc(w->obs, w->first, w->next_out, w->last);
                        state->from = w->next_out;
                    }
                    state->sent_any = true;
                    state->last_sent = std::chrono::steady_clock::now();
                    lock.unlock();
                    const std::string part = fmt::format("--a5e4f3c2-fixture\r\nContent-type: text/xml\r\n"
                                                         "Content-length: {}\r\n\r\n{}\r\n",
                                                         body.size(), body);
                    if (!sink.write(part.data(), part.size())) return false;
                    if (end) sink.done();
                    return true;
                });
        });
    }

    struct StreamState {
        std::uint64_t from = 0;
        std::uint64_t instance = 0;
        bool sent_any = false;
        std::chrono::steady_clock::time_point last_sent{};
    };

    const std::vector<Item> items_;
    const std::string device_;
    const std::size_t buffer_size_;
    std::unique_ptr<httplib::Server> server_;
    std::thread thread_;
    int port_ = 0;

    mutable std::mutex mu_;
    std::condition_variable cv_;
    std::deque<Published> buffer_;
    std::map<std::string, Published> latest_;
    std::uint64_t next_seq_ = 1, first_override_ = 0, instance_ = 1700000000;
    bool hold_ = false, stopping_ = false;
    std::size_t held_now_ = 0;
    std::map<std::string, std::size_t> requests_;
};

}  // namespace cutload::live::test
