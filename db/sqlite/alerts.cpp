// SQLite: thresholds, alerts, webhooks and their deliveries.
#include "sqlite/store.hpp"

#include <fmt/format.h>

namespace cutload::db::sqlite {
namespace {

// ---- thresholds ------------------------------------------------------------------------------

constexpr const char* kThresholdSelect =
    "SELECT id, name, scope, machine_id, tool_id, material_id, metric, flag, limit_value, severity, enabled, created_at "
    "FROM thresholds ";

ThresholdRecord threshold_row(const Stmt& st) {
    ThresholdRecord t;
    t.id = st.i64(0);
    t.name = st.text(1);
    t.scope = st.text(2);
    t.machine_id = st.opt_i64(3);
    t.tool_id = st.opt_i64(4);
    t.material_id = st.opt_i64(5);
    t.metric = st.text(6);
    t.flag = st.opt_text(7);
    t.limit = st.opt_real(8);
    t.severity = st.text(9);
    t.enabled = st.i64(10) != 0;
    t.created_at = st.text(11);
    return t;
}

void bind_rule(Stmt& st, const ThresholdRule& r) {
    st.bind(1, r.name).bind(2, r.scope).bind(3, r.machine_id).bind(4, r.tool_id).bind(5, r.material_id);
    st.bind(6, r.metric).bind(7, r.flag).bind(8, r.limit).bind(9, r.severity).bind(10, r.enabled);
}

std::vector<ThresholdRecord> thresholds_of(Stmt st) {
    std::vector<ThresholdRecord> out;
    while (st.step()) out.push_back(threshold_row(st));
    return out;
}

// ---- alerts ----------------------------------------------------------------------------------

constexpr const char* kAlertSelect =
    "SELECT a.id, a.run_id, a.threshold_id, a.severity, a.body, a.created_at, a.acked_at, a.acked_by, a.ack_note, "
    "r.name, r.program, r.machine_id FROM alerts a JOIN runs r ON r.id = a.run_id ";

AlertRecord alert_row(const Stmt& st) {
    AlertRecord a;
    a.id = st.i64(0);
    a.run_id = st.i64(1);
    a.threshold_id = st.opt_i64(2);
    a.severity = st.text(3);
    a.body_json = st.text(4);
    a.created_at = st.text(5);
    a.acked_at = st.opt_text(6);
    a.acked_by = st.opt_text(7);
    a.ack_note = st.opt_text(8);
    a.run_name = st.opt_text(9);
    a.run_program = st.opt_text(10);
    a.run_machine_id = st.opt_i64(11);
    return a;
}

// ---- webhooks --------------------------------------------------------------------------------

constexpr const char* kWebhookSelect = "SELECT id, url, secret, enabled, created_at FROM webhooks ";

WebhookRecord webhook_row(const Stmt& st) {
    return WebhookRecord{st.i64(0), st.text(1), st.opt_text(2), st.i64(3) != 0, st.text(4)};
}

}  // namespace

std::vector<ThresholdRecord> Thresholds::list() { return thresholds_of(c_.prepare(std::string(kThresholdSelect) + "ORDER BY id")); }

std::vector<ThresholdRecord> Thresholds::enabled() {
    return thresholds_of(c_.prepare(std::string(kThresholdSelect) + "WHERE enabled = 1 ORDER BY id"));
}

std::optional<ThresholdRecord> Thresholds::get(std::int64_t id) {
    auto st = c_.prepare(std::string(kThresholdSelect) + "WHERE id = ?");
    st.bind(1, id);
    if (!st.step()) return std::nullopt;
    return threshold_row(st);
}

std::int64_t Thresholds::create(const ThresholdRule& r, const std::string& now) {
    auto st = c_.prepare(
        "INSERT INTO thresholds(name, scope, machine_id, tool_id, material_id, metric, flag, limit_value, severity, "
        "enabled, created_at) VALUES (?,?,?,?,?,?,?,?,?,?,?)");
    bind_rule(st, r);
    st.bind(11, now).run();
    return c_.last_insert_id();
}

bool Thresholds::update(std::int64_t id, const ThresholdRule& r) {
    auto st = c_.prepare(
        "UPDATE thresholds SET name = ?, scope = ?, machine_id = ?, tool_id = ?, material_id = ?, metric = ?, "
        "flag = ?, limit_value = ?, severity = ?, enabled = ? WHERE id = ?");
    bind_rule(st, r);
    st.bind(11, id).run();
    return c_.changes() > 0;
}

bool Thresholds::remove(std::int64_t id) {
    c_.prepare("DELETE FROM thresholds WHERE id = ?").bind(1, id).run();
    return c_.changes() > 0;
}

std::int64_t Alerts::create(std::int64_t run_id, std::optional<std::int64_t> threshold_id, const std::string& severity,
                            const std::string& body_json, const std::string& now) {
    c_.prepare("INSERT INTO alerts(run_id, threshold_id, severity, body, created_at) VALUES (?,?,?,?,?)")
        .bind(1, run_id)
        .bind(2, threshold_id)
        .bind(3, severity)
        .bind(4, body_json)
        .bind(5, now)
        .run();
    return c_.last_insert_id();
}

std::optional<AlertRecord> Alerts::get(std::int64_t id) {
    auto st = c_.prepare(std::string(kAlertSelect) + "WHERE a.id = ?");
    st.bind(1, id);
    if (!st.step()) return std::nullopt;
    return alert_row(st);
}

std::vector<AlertRecord> Alerts::list(const AlertFilter& f) {
    auto st = c_.prepare(std::string(kAlertSelect) +
                         "WHERE (?1 IS NULL OR a.id < ?1) AND (?2 IS NULL OR a.run_id = ?2) AND (?3 IS NULL OR a.severity = ?3) "
                         "AND (?4 IS NULL OR (a.acked_at IS NOT NULL) = ?4) AND (?5 IS NULL OR r.machine_id = ?5) "
                         "AND (?6 IS NULL OR a.threshold_id = ?6) AND (?7 IS NULL OR a.created_at >= ?7) "
                         "AND (?8 IS NULL OR a.created_at <= ?8) ORDER BY a.id DESC LIMIT ?9");
    st.bind(1, f.before_id).bind(2, f.run_id).bind(3, f.severity).bind(4, f.acked).bind(5, f.machine_id);
    st.bind(6, f.threshold_id).bind(7, f.since).bind(8, f.until).bind(9, f.limit);
    std::vector<AlertRecord> out;
    while (st.step()) out.push_back(alert_row(st));
    return out;
}

void Alerts::acknowledge(std::int64_t id, const std::string& at, const std::string& by, const std::optional<std::string>& note) {
    c_.prepare("UPDATE alerts SET acked_at = ?, acked_by = ?, ack_note = ? WHERE id = ? AND acked_at IS NULL")
        .bind(1, at)
        .bind(2, by)
        .bind(3, note)
        .bind(4, id)
        .run();
}

std::vector<WebhookRecord> Webhooks::list() {
    auto st = c_.prepare(std::string(kWebhookSelect) + "ORDER BY id");
    std::vector<WebhookRecord> out;
    while (st.step()) out.push_back(webhook_row(st));
    return out;
}

std::optional<WebhookRecord> Webhooks::get(std::int64_t id) {
    auto st = c_.prepare(std::string(kWebhookSelect) + "WHERE id = ?");
    st.bind(1, id);
    if (!st.step()) return std::nullopt;
    return webhook_row(st);
}

std::int64_t Webhooks::create(const std::string& url, const std::optional<std::string>& secret, bool enabled,
                              const std::string& now) {
    c_.prepare("INSERT INTO webhooks(url, secret, enabled, created_at) VALUES (?,?,?,?)")
        .bind(1, url)
        .bind(2, secret)
        .bind(3, enabled)
        .bind(4, now)
        .run();
    return c_.last_insert_id();
}

bool Webhooks::update(std::int64_t id, const std::string& url, const std::optional<std::string>& secret, bool enabled) {
    c_.prepare("UPDATE webhooks SET url = ?, secret = ?, enabled = ? WHERE id = ?")
        .bind(1, url)
        .bind(2, secret)
        .bind(3, enabled)
        .bind(4, id)
        .run();
    return c_.changes() > 0;
}

bool Webhooks::remove(std::int64_t id) {
    c_.prepare("DELETE FROM webhooks WHERE id = ?").bind(1, id).run();
    return c_.changes() > 0;
}

std::vector<std::int64_t> Webhooks::enabled_ids() {
    auto st = c_.prepare("SELECT id FROM webhooks WHERE enabled = 1");
    std::vector<std::int64_t> out;
    while (st.step()) out.push_back(st.i64(0));
    return out;
}

void Webhooks::enqueue(std::int64_t webhook_id, std::int64_t alert_id, const std::string& payload, double next_attempt_unix,
                       const std::string& now) {
    c_.prepare(
          "INSERT INTO webhook_deliveries(webhook_id, alert_id, payload, state, attempts, next_attempt_unix, created_at) "
          "VALUES (?,?,?,?,0,?,?)")
        .bind(1, webhook_id)
        .bind(2, alert_id)
        .bind(3, payload)
        .bind(4, to_text(DeliveryState::Pending))
        .bind(5, next_attempt_unix)
        .bind(6, now)
        .run();
}

std::vector<DueDelivery> Webhooks::due(double now_unix, std::int64_t limit) {
    auto st = c_.prepare(
        "SELECT d.id, w.url, w.secret, d.payload, d.attempts FROM webhook_deliveries d "
        "JOIN webhooks w ON w.id = d.webhook_id WHERE d.state = ?1 AND d.next_attempt_unix <= ?2 "
        "ORDER BY d.next_attempt_unix LIMIT ?3");
    st.bind(1, to_text(DeliveryState::Pending)).bind(2, now_unix).bind(3, limit);
    std::vector<DueDelivery> out;
    while (st.step()) out.push_back(DueDelivery{st.i64(0), st.text(1), st.opt_text(2), st.text(3), st.i64(4)});
    return out;
}

void Webhooks::record_attempt(std::int64_t delivery_id, const DeliveryAttempt& a, DeliveryState state,
                              double next_attempt_unix, const std::optional<std::string>& delivered_at) {
    Savepoint sp(c_, "record_attempt");
    c_.prepare("INSERT INTO webhook_attempts(delivery_id, attempt, at, status, error, duration_ms) VALUES (?,?,?,?,?,?)")
        .bind(1, delivery_id)
        .bind(2, a.attempt)
        .bind(3, a.at)
        .bind(4, a.http_status)
        .bind(5, a.error)
        .bind(6, a.duration_ms)
        .run();
    c_.prepare("UPDATE webhook_deliveries SET attempts = ?, state = ?, next_attempt_unix = ?, delivered_at = ? WHERE id = ?")
        .bind(1, a.attempt)
        .bind(2, to_text(state))
        .bind(3, next_attempt_unix)
        .bind(4, delivered_at)
        .bind(5, delivery_id)
        .run();
    sp.release();
}

std::vector<DeliveryRecord> Webhooks::deliveries(std::int64_t webhook_id, std::optional<std::int64_t> before_id,
                                                 std::int64_t limit) {
    auto st = c_.prepare(
        "SELECT id, alert_id, state, attempts, next_attempt_unix, created_at, delivered_at FROM webhook_deliveries "
        "WHERE webhook_id = ?1 AND (?2 IS NULL OR id < ?2) ORDER BY id DESC LIMIT ?3");
    st.bind(1, webhook_id).bind(2, before_id).bind(3, limit);
    auto at = c_.prepare(
        "SELECT attempt, at, status, error, duration_ms FROM webhook_attempts WHERE delivery_id = ? ORDER BY attempt");
    std::vector<DeliveryRecord> out;
    while (st.step()) {
        DeliveryRecord d{st.i64(0), st.opt_i64(1), delivery_state_from_text(st.text(2)), st.i64(3), st.real(4), st.text(5),
                         st.opt_text(6), {}};
        at.reset();
        at.bind(1, d.id);
        while (at.step()) d.log.push_back(DeliveryAttempt{at.i64(0), at.text(1), at.opt_i64(2), at.opt_text(3), at.real(4)});
        out.push_back(std::move(d));
    }
    return out;
}

std::optional<double> Webhooks::next_pending_unix() {
    auto st = c_.prepare("SELECT min(next_attempt_unix) FROM webhook_deliveries WHERE state = ?");
    st.bind(1, to_text(DeliveryState::Pending));
    if (!st.step()) return std::nullopt;
    return st.opt_real(0);
}

std::int64_t Webhooks::pending_count() {
    auto st = c_.prepare("SELECT count(*) FROM webhook_deliveries WHERE state = ?");
    st.bind(1, to_text(DeliveryState::Pending));
    st.step();
    return st.i64(0);
}

}  // namespace cutload::db::sqlite
