// Internal to server: delivers pending webhook rows by POST, with exponential backoff between
// attempts and every attempt logged. Pending rows survive restarts (they are in the database).
#pragma once

#include "common.hpp"
#include "metrics.hpp"

#include <condition_variable>
#include <mutex>
#include <thread>

namespace cutload::server {

class Webhooks {
public:
    Webhooks(db::Store& store, const ServerOptions& opt, Metrics& metrics);
    ~Webhooks();
    void start();
    void notify();
    void stop();

private:
    void loop();
    // Returns seconds until the next pending delivery is due (or a long wait when none is).
    double deliver_due();

    db::Store& store_;
    const ServerOptions& opt_;
    Metrics& metrics_;
    std::mutex mu_;
    std::condition_variable cv_;
    bool stopping_ = false, poked_ = false;
    std::thread thread_;
};

// Splits "http://host:port/path" (or https); false when it is not such a URL. `host` (optional)
// gets the host name or address without brackets or port.
bool split_http_url(const std::string& url, std::string* origin, std::string* path, std::string* host = nullptr);

// Why a webhook may not be sent to `host`, or "" when it may. Link-local addresses (169.254/16,
// fe80::/10: where cloud metadata services answer), unspecified and multicast addresses are
// refused, and so is an IPv6 address that carries such an IPv4 address (v4-mapped, v4-compatible,
// NAT64 64:ff9b::/96, SIIT, 6to4, Teredo, ISATAP). Loopback and private networks are allowed: MES and alerting hosts live there. Without
// `resolve` only address literals are checked (at registration); with it, every address the name
// resolves to (before each delivery, so a name cannot be pointed there later).
std::string refused_webhook_host(const std::string& host, bool resolve);

}  // namespace cutload::server
