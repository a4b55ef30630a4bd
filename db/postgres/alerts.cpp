// PostgreSQL: thresholds, alerts, webhooks and their deliveries.
#include "postgres/store.hpp"

namespace cutload::db::postgres {
namespace {

// ---- thresholds ------------------------------------------------------------------------------

constexpr const char* kThresholdSelect =
    "SELECT id, name, scope, machine_id, tool_id, material_id, metric, flag, limit_value, severity, enabled, created_at "
    "FROM thresholds ";

ThresholdRecord threshold_row(const Result& r, int i) {
    ThresholdRecord t;
    t.id = r.i64(i, 0);
    t.name = r.text(i, 1);
    t.scope = r.text(i, 2);
    t.machine_id = r.opt_i64(i, 3);
    t.tool_id = r.opt_i64(i, 4);
    t.material_id = r.opt_i64(i, 5);
    t.metric = r.text(i, 6);
    t.flag = r.opt_text(i, 7);
    t.limit = r.opt_real(i, 8);
    t.severity = r.text(i, 9);
    t.enabled = r.boolean(i, 10);
    t.created_at = r.text(i, 11);
    return t;
}

Params rule_params(const ThresholdRule& r) {
    Params p;
    p.add(r.name).add(r.scope).add(r.machine_id).add(r.tool_id).add(r.material_id);
    p.add(r.metric).add(r.flag).add(r.limit).add(r.severity).add(r.enabled);
    return p;
}

std::vector<ThresholdRecord> thresholds_of(const Result& r) {
    std::vector<ThresholdRecord> out;
    for (int i = 0; i < r.rows(); ++i) out.push_back(threshold_row(r, i));
    return out;
}

// ---- alerts ----------------------------------------------------------------------------------

constexpr const char* kAlertSelect =
    "SELECT a.id, a.run_id, a.threshold_id, a.severity, a.body, a.created_at, a.acked_at, a.acked_by, a.ack_note, "
    "r.name, r.program, r.machine_id FROM alerts a JOIN runs r ON r.id = a.run_id ";

AlertRecord alert_row(const Result& r, int i) {
    AlertRecord a;
    a.id = r.i64(i, 0);
    a.run_id = r.i64(i, 1);
    a.threshold_id = r.opt_i64(i, 2);
    a.severity = r.text(i, 3);
    a.body_json = r.text(i, 4);
    a.created_at = r.text(i, 5);
    a.acked_at = r.opt_text(i, 6);
    a.acked_by = r.opt_text(i, 7);
    a.ack_note = r.opt_text(i, 8);
    a.run_name = r.opt_text(i, 9);
    a.run_program = r.opt_text(i, 10);
    a.run_machine_id = r.opt_i64(i, 11);
    return a;
}

// ---- webhooks --------------------------------------------------------------------------------

constexpr const char* kWebhookSelect = "SELECT id, url, secret, enabled, created_at FROM webhooks ";

WebhookRecord webhook_row(const Result& r, int i) {
    return WebhookRecord{r.i64(i, 0), r.text(i, 1), r.opt_text(i, 2), r.boolean(i, 3), r.text(i, 4)};
}

}  // namespace

std::vector<ThresholdRecord> Thresholds::list() { return thresholds_of(c_.run(std::string(kThresholdSelect) + "ORDER BY id")); }

std::vector<ThresholdRecord> Thresholds::enabled() {
    return thresholds_of(c_.run(std::string(kThresholdSelect) + "WHERE enabled ORDER BY id"));
}

std::optional<ThresholdRecord> Thresholds::get(std::int64_t id) {
    auto r = c_.run(std::string(kThresholdSelect) + "WHERE id = $1", Params().add(id));
    if (r.empty()) return std::nullopt;
    return threshold_row(r, 0);
}

std::int64_t Thresholds::create(const ThresholdRule& rule, const std::string& now) {
    Params p = rule_params(rule);
    p.add(now);
    return c_
        .run("INSERT INTO thresholds(name, scope, machine_id, tool_id, material_id, metric, flag, limit_value, severity, "
             "enabled, created_at) VALUES ($1,$2,$3,$4,$5,$6,$7,$8,$9,$10,$11) RETURNING id",
             p)
        .i64(0, 0);
}

bool Thresholds::update(std::int64_t id, const ThresholdRule& rule) {
    Params p = rule_params(rule);
    p.add(id);
    return c_.run("UPDATE thresholds SET name = $1, scope = $2, machine_id = $3, tool_id = $4, material_id = $5, metric = $6, "
                  "flag = $7, limit_value = $8, severity = $9, enabled = $10 WHERE id = $11",
                  p)
               .affected() > 0;
}

bool Thresholds::remove(std::int64_t id) {
    return c_.run("DELETE FROM thresholds WHERE id = $1", Params().add(id)).affected() > 0;
}

std::int64_t Alerts::create(std::int64_t run_id, std::optional<std::int64_t> threshold_id, const std::string& severity,
                            const std::string& body_json, const std::string& now) {
    return c_
        .run("INSERT INTO alerts(run_id, threshold_id, severity, body, created_at) VALUES ($1,$2,$3,$4,$5) RETURNING id",
             Params().add(run_id).add(threshold_id).add(severity).add(body_json).add(now))
        .i64(0, 0);
}

std::optional<AlertRecord> Alerts::get(std::int64_t id) {
    auto r = c_.run(std::string(kAlertSelect) + "WHERE a.id = $1", Params().add(id));
    if (r.empty()) return std::nullopt;
    return alert_row(r, 0);
}

std::vector<AlertRecord> Alerts::list(const AlertFilter& f) {
    auto r = c_.run(std::string(kAlertSelect) +
                        "WHERE ($1::bigint IS NULL OR a.id < $1) AND ($2::bigint IS NULL OR a.run_id = $2) "
                        "AND ($3::text IS NULL OR a.severity = $3) AND ($4::boolean IS NULL OR (a.acked_at IS NOT NULL) = $4) "
                        "AND ($5::bigint IS NULL OR r.machine_id = $5) AND ($6::bigint IS NULL OR a.threshold_id = $6) "
                        "AND ($7::text IS NULL OR a.created_at >= $7) AND ($8::text IS NULL OR a.created_at <= $8) "
                        "ORDER BY a.id DESC LIMIT $9",
                    Params()
                        .add(f.before_id)
                        .add(f.run_id)
                        .add(f.severity)
                        .add(f.acked)
                        .add(f.machine_id)
                        .add(f.threshold_id)
                        .add(f.since)
                        .add(f.until)
                        .add(f.limit));
    std::vector<AlertRecord> out;
    for (int i = 0; i < r.rows(); ++i) out.push_back(alert_row(r, i));
    return out;
}

void Alerts::acknowledge(std::int64_t id, const std::string& at, const std::string& by, const std::optional<std::string>& note) {
    c_.run("UPDATE alerts SET acked_at = $1, acked_by = $2, ack_note = $3 WHERE id = $4 AND acked_at IS NULL",
           Params().add(at).add(by).add(note).add(id));
}

std::vector<WebhookRecord> Webhooks::list() {
    auto r = c_.run(std::string(kWebhookSelect) + "ORDER BY id");
    std::vector<WebhookRecord> out;
    for (int i = 0; i < r.rows(); ++i) out.push_back(webhook_row(r, i));
    return out;
}

std::optional<WebhookRecord> Webhooks::get(std::int64_t id) {
    auto r = c_.run(std::string(kWebhookSelect) + "WHERE id = $1", Params().add(id));
    if (r.empty()) return std::nullopt;
    return webhook_row(r, 0);
}

std::int64_t Webhooks::create(const std::string& url, const std::optional<std::string>& secret, bool enabled,
                              const std::string& now) {
    return c_
        .run("INSERT INTO webhooks(url, secret, enabled, created_at) VALUES ($1,$2,$3,$4) RETURNING id",
             Params().add(url).add(secret).add(enabled).add(now))
        .i64(0, 0);
}

bool Webhooks::update(std::int64_t id, const std::string& url, const std::optional<std::string>& secret, bool enabled) {
    return c_.run("UPDATE webhooks SET url = $1, secret = $2, enabled = $3 WHERE id = $4",
                  Params().add(url).add(secret).add(enabled).add(id))
               .affected() > 0;
}

bool Webhooks::remove(std::int64_t id) {
    return c_.run("DELETE FROM webhooks WHERE id = $1", Params().add(id)).affected() > 0;
}

std::vector<std::int64_t> Webhooks::enabled_ids() {
    auto r = c_.run("SELECT id FROM webhooks WHERE enabled ORDER BY id");
    std::vector<std::int64_t> out;
    for (int i = 0; i < r.rows(); ++i) out.push_back(r.i64(i, 0));
    return out;
}

void Webhooks::enqueue(std::int64_t webhook_id, std::int64_t alert_id, const std::string& payload, double next_attempt_unix,
                       const std::string& now) {
    c_.run("INSERT INTO webhook_deliveries(webhook_id, alert_id, payload, state, attempts, next_attempt_unix, created_at) "
           "VALUES ($1,$2,$3,$4,0,$5,$6)",
           Params().add(webhook_id).add(alert_id).add(payload).add(to_text(DeliveryState::Pending)).add(next_attempt_unix).add(now));
}

std::vector<DueDelivery> Webhooks::due(double now_unix, std::int64_t limit) {
    auto r = c_.run("SELECT d.id, w.url, w.secret, d.payload, d.attempts FROM webhook_deliveries d "
                    "JOIN webhooks w ON w.id = d.webhook_id WHERE d.state = $1 AND d.next_attempt_unix <= $2 "
                    "ORDER BY d.next_attempt_unix LIMIT $3",
                    Params().add(to_text(DeliveryState::Pending)).add(now_unix).add(limit));
    std::vector<DueDelivery> out;
    for (int i = 0; i < r.rows(); ++i)
        out.push_back(DueDelivery{r.i64(i, 0), r.text(i, 1), r.opt_text(i, 2), r.text(i, 3), r.i64(i, 4)});
    return out;
}

void Webhooks::record_attempt(std::int64_t delivery_id, const DeliveryAttempt& a, DeliveryState state,
                              double next_attempt_unix, const std::optional<std::string>& delivered_at) {
    // One statement, so the attempt and the delivery's move on are atomic without a transaction.
    c_.run("WITH logged AS (INSERT INTO webhook_attempts(delivery_id, attempt, at, status, error, duration_ms) "
           "VALUES ($1,$2,$3,$4,$5,$6)) "
           "UPDATE webhook_deliveries SET attempts = $2, state = $7, next_attempt_unix = $8, delivered_at = $9 WHERE id = $1",
           Params()
               .add(delivery_id)
               .add(a.attempt)
               .add(a.at)
               .add(a.http_status)
               .add(a.error)
               .add(a.duration_ms)
               .add(to_text(state))
               .add(next_attempt_unix)
               .add(delivered_at));
}

std::vector<DeliveryRecord> Webhooks::deliveries(std::int64_t webhook_id, std::optional<std::int64_t> before_id,
                                                 std::int64_t limit) {
    auto r = c_.run("SELECT id, alert_id, state, attempts, next_attempt_unix, created_at, delivered_at FROM webhook_deliveries "
                    "WHERE webhook_id = $1 AND ($2::bigint IS NULL OR id < $2) ORDER BY id DESC LIMIT $3",
                    Params().add(webhook_id).add(before_id).add(limit));
    std::vector<DeliveryRecord> out;
    for (int i = 0; i < r.rows(); ++i) {
        DeliveryRecord d{r.i64(i, 0), r.opt_i64(i, 1), delivery_state_from_text(r.text(i, 2)), r.i64(i, 3), r.real(i, 4),
                         r.text(i, 5), r.opt_text(i, 6), {}};
        auto at = c_.run("SELECT attempt, at, status, error, duration_ms FROM webhook_attempts WHERE delivery_id = $1 "
                         "ORDER BY attempt",
                         Params().add(d.id));
        for (int j = 0; j < at.rows(); ++j)
            d.log.push_back(DeliveryAttempt{at.i64(j, 0), at.text(j, 1), at.opt_i64(j, 2), at.opt_text(j, 3), at.real(j, 4)});
        out.push_back(std::move(d));
    }
    return out;
}

std::optional<double> Webhooks::next_pending_unix() {
    auto r = c_.run("SELECT min(next_attempt_unix) FROM webhook_deliveries WHERE state = $1",
                    Params().add(to_text(DeliveryState::Pending)));
    if (r.empty()) return std::nullopt;
    return r.opt_real(0, 0);
}

std::int64_t Webhooks::pending_count() {
    return c_.run("SELECT count(*) FROM webhook_deliveries WHERE state = $1", Params().add(to_text(DeliveryState::Pending)))
        .i64(0, 0);
}

}  // namespace cutload::db::postgres
