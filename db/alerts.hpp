// Public interface of db: threshold rules, the alerts finished runs raise, webhook subscriptions
// and their deliveries (each attempt logged).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace cutload::db {

// ---- thresholds ------------------------------------------------------------------------------

struct ThresholdRule {
    std::string name;
    std::string scope;    // any, machine, tool, material
    std::optional<std::int64_t> machine_id, tool_id, material_id;   // the one of the scope
    std::string metric;
    std::optional<std::string> flag;   // metric "flag" only
    std::optional<double> limit;       // every other metric
    std::string severity;
    bool enabled = true;
};

struct ThresholdRecord : ThresholdRule {
    std::int64_t id = 0;
    std::string created_at;
};

class ThresholdRepository {
public:
    virtual ~ThresholdRepository() = default;
    virtual std::vector<ThresholdRecord> list() = 0;   // by id
    virtual std::vector<ThresholdRecord> enabled() = 0;
    virtual std::optional<ThresholdRecord> get(std::int64_t id) = 0;
    virtual std::int64_t create(const ThresholdRule& r, const std::string& now) = 0;
    virtual bool update(std::int64_t id, const ThresholdRule& r) = 0;
    virtual bool remove(std::int64_t id) = 0;
};

// ---- alerts ----------------------------------------------------------------------------------

struct AlertRecord {
    std::int64_t id = 0;
    std::int64_t run_id = 0;
    std::optional<std::int64_t> threshold_id;   // null once the rule is deleted
    std::string severity;
    std::string body_json;                      // metric, value, limit, blocks, message
    std::string created_at;
    std::optional<std::string> acked_at, acked_by, ack_note;
    // Of the run that raised it.
    std::optional<std::string> run_name, run_program;
    std::optional<std::int64_t> run_machine_id;
};

// Newest first; each field narrows the list when set.
struct AlertFilter {
    std::optional<std::int64_t> before_id, run_id, machine_id, threshold_id;
    std::optional<std::string> severity;
    std::optional<bool> acked;
    std::optional<std::string> since, until;   // inclusive, ISO 8601 text
    std::int64_t limit = 100;
};

class AlertRepository {
public:
    virtual ~AlertRepository() = default;
    virtual std::int64_t create(std::int64_t run_id, std::optional<std::int64_t> threshold_id, const std::string& severity,
                                const std::string& body_json, const std::string& now) = 0;
    virtual std::optional<AlertRecord> get(std::int64_t id) = 0;
    virtual std::vector<AlertRecord> list(const AlertFilter& f) = 0;
    // The first acknowledgement is kept; acknowledging again changes nothing.
    virtual void acknowledge(std::int64_t id, const std::string& at, const std::string& by,
                             const std::optional<std::string>& note) = 0;
};

// ---- webhooks and deliveries -----------------------------------------------------------------

struct WebhookRecord {
    std::int64_t id = 0;
    std::string url;
    std::optional<std::string> secret;
    bool enabled = true;
    std::string created_at;
};

enum class DeliveryState { Pending, Delivered, Failed };
std::string_view to_text(DeliveryState s);
// Throws std::invalid_argument for anything that is not a delivery state.
DeliveryState delivery_state_from_text(std::string_view text);

struct DeliveryAttempt {
    std::int64_t attempt = 0;                  // 1, 2, ...
    std::string at;
    std::optional<std::int64_t> http_status;   // none when no answer came
    std::optional<std::string> error;          // none when delivered
    double duration_ms = 0;
};

struct DeliveryRecord {
    std::int64_t id = 0;
    std::optional<std::int64_t> alert_id;
    DeliveryState state = DeliveryState::Pending;
    std::int64_t attempts = 0;
    double next_attempt_unix = 0;
    std::string created_at;
    std::optional<std::string> delivered_at;
    std::vector<DeliveryAttempt> log;   // oldest first
};

// A pending delivery whose time has come, with where it goes.
struct DueDelivery {
    std::int64_t id = 0;
    std::string url;
    std::optional<std::string> secret;
    std::string payload;
    std::int64_t attempts = 0;
};

class WebhookRepository {
public:
    virtual ~WebhookRepository() = default;
    virtual std::vector<WebhookRecord> list() = 0;   // by id
    virtual std::optional<WebhookRecord> get(std::int64_t id) = 0;
    virtual std::int64_t create(const std::string& url, const std::optional<std::string>& secret, bool enabled,
                                const std::string& now) = 0;
    virtual bool update(std::int64_t id, const std::string& url, const std::optional<std::string>& secret, bool enabled) = 0;
    virtual bool remove(std::int64_t id) = 0;
    virtual std::vector<std::int64_t> enabled_ids() = 0;

    // A pending delivery of `payload` to webhook `webhook_id`, first tried at next_attempt_unix.
    virtual void enqueue(std::int64_t webhook_id, std::int64_t alert_id, const std::string& payload,
                         double next_attempt_unix, const std::string& now) = 0;
    // Pending deliveries due at `now_unix`, soonest first, at most `limit`.
    virtual std::vector<DueDelivery> due(double now_unix, std::int64_t limit) = 0;
    // Logs an attempt and moves the delivery on, atomically: `state` after it, when to try next,
    // and when it was delivered.
    virtual void record_attempt(std::int64_t delivery_id, const DeliveryAttempt& a, DeliveryState state,
                                double next_attempt_unix, const std::optional<std::string>& delivered_at) = 0;
    // Newest first, ids below before_id when set, each with its log.
    virtual std::vector<DeliveryRecord> deliveries(std::int64_t webhook_id, std::optional<std::int64_t> before_id,
                                                   std::int64_t limit) = 0;
    virtual std::optional<double> next_pending_unix() = 0;
    virtual std::int64_t pending_count() = 0;
};

}  // namespace cutload::db
