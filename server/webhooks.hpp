// Internal to server: delivers pending webhook rows by POST, with exponential backoff between
// attempts and every attempt logged. Pending rows survive restarts (they are in the database).
#pragma once

#include "server/common.hpp"
#include "server/metrics.hpp"

#include <thread>

namespace cutload::server {

class Webhooks {
public:
    Webhooks(DbPool& pool, const ServerOptions& opt, Metrics& metrics);
    ~Webhooks();
    void start();
    void notify();
    void stop();

private:
    void loop();
    // Returns seconds until the next pending delivery is due (or a long wait when none is).
    double deliver_due();

    DbPool& pool_;
    const ServerOptions& opt_;
    Metrics& metrics_;
    std::mutex mu_;
    std::condition_variable cv_;
    bool stopping_ = false, poked_ = false;
    std::thread thread_;
};

// Splits "http://host:port/path" (or https); false when it is not such a URL.
bool split_http_url(const std::string& url, std::string* origin, std::string* path);

}  // namespace cutload::server
