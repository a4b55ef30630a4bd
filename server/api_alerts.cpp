// Routes: /api/v1/thresholds (rules), /api/v1/alerts (raised by finished runs, acknowledged by
// people) and /api/v1/webhooks (subscriptions and their delivery log).
#include "core.hpp"
#include "results.hpp"
#include "webhooks.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <regex>

namespace cutload::server {
namespace {

bool one_of(const std::string& v, const std::vector<std::string>& set) {
    return std::find(set.begin(), set.end(), v) != set.end();
}

std::string join(const std::vector<std::string>& v) {
    std::string s;
    for (const auto& x : v) s += (s.empty() ? "" : ", ") + x;
    return s;
}

std::string req_string(const json& b, const char* key) {
    if (!b.contains(key) || !b[key].is_string() || b[key].get<std::string>().empty())
        bad_request(fmt::format("{}: required non-empty string", key));
    return b[key].get<std::string>();
}

// ---- thresholds ---------------------------------------------------------------------------

struct Threshold {
    std::string name, scope, metric, flag, severity;
    std::optional<std::int64_t> scope_id;
    std::optional<double> limit;
    bool enabled = true;
};

Threshold validate_threshold(db::Connection& c, const json& b) {
    if (!b.is_object()) bad_request("body must be a JSON object");
    static const std::vector<std::string> keys{"name", "scope", "machine_id", "tool_id", "material_id", "metric",
                                               "flag", "limit", "severity", "enabled"};
    for (const auto& [k, v] : b.items())
        if (!one_of(k, keys)) bad_request(fmt::format("{}: unknown key (expected {})", k, join(keys)));
    Threshold t;
    t.name = req_string(b, "name");
    t.scope = b.value("scope", "any");
    if (!one_of(t.scope, {"any", "machine", "tool", "material"}))
        bad_request(fmt::format("scope: '{}' is not any, machine, tool or material", t.scope));
    if (t.scope != "any") {
        const std::string key = t.scope + "_id";
        if (!b.contains(key) || !b[key].is_number_integer())
            bad_request(fmt::format("{}: required integer when scope is {}", key, t.scope));
        t.scope_id = b[key].get<std::int64_t>();
        auto st = c.prepare(fmt::format("SELECT 1 FROM {}s WHERE id = ?", t.scope));
        st.bind(1, *t.scope_id);
        if (!st.step()) not_found(fmt::format("{} {}: no such {}", key, *t.scope_id, t.scope));
    }
    t.metric = req_string(b, "metric");
    if (!one_of(t.metric, threshold_metrics()))
        bad_request(fmt::format("metric: '{}' is not one of {}", t.metric, join(threshold_metrics())));
    if (t.metric == "flag") {
        t.flag = b.value("flag", "any");
        if (!one_of(t.flag, known_flags())) bad_request(fmt::format("flag: '{}' is not one of {}", t.flag, join(known_flags())));
    } else {
        if (!b.contains("limit") || !b["limit"].is_number() || b["limit"].get<double>() < 0)
            bad_request(fmt::format("limit: required number >= 0 for metric {}", t.metric));
        t.limit = b["limit"].get<double>();
    }
    t.severity = b.value("severity", "warning");
    if (!one_of(t.severity, {"info", "warning", "critical"}))
        bad_request(fmt::format("severity: '{}' is not info, warning or critical", t.severity));
    if (b.contains("enabled")) {
        if (!b["enabled"].is_boolean()) bad_request("enabled: must be true or false");
        t.enabled = b["enabled"].get<bool>();
    }
    return t;
}

constexpr const char* kThresholdCols =
    "id, name, scope, machine_id, tool_id, material_id, metric, flag, limit_value, severity, enabled, created_at";

json threshold_json(const db::Stmt& st) {
    json j{{"id", st.i64(0)},          {"name", st.text(1)},     {"scope", st.text(2)},
           {"metric", st.text(6)},     {"severity", st.text(9)}, {"enabled", st.i64(10) != 0},
           {"created_at", st.text(11)}};
    const char* id_cols[] = {"machine_id", "tool_id", "material_id"};
    for (int i = 0; i < 3; ++i)
        if (!st.is_null(3 + i)) j[id_cols[i]] = st.i64(3 + i);
    j["flag"] = st.is_null(7) ? json(nullptr) : json(st.text(7));
    j["limit"] = st.is_null(8) ? json(nullptr) : json(st.real(8));
    return j;
}

json load_threshold(db::Connection& c, std::int64_t id) {
    auto st = c.prepare(fmt::format("SELECT {} FROM thresholds WHERE id = ?", kThresholdCols));
    st.bind(1, id);
    if (!st.step()) not_found(fmt::format("threshold {} does not exist", id));
    return threshold_json(st);
}

void bind_threshold(db::Stmt& st, const Threshold& t) {
    st.bind(1, t.name).bind(2, t.scope);
    st.bind(3, t.scope == "machine" ? t.scope_id : std::nullopt);
    st.bind(4, t.scope == "tool" ? t.scope_id : std::nullopt);
    st.bind(5, t.scope == "material" ? t.scope_id : std::nullopt);
    st.bind(6, t.metric);
    st.bind(7, t.metric == "flag" ? std::optional<std::string>(t.flag) : std::nullopt);
    st.bind(8, t.limit).bind(9, t.severity).bind(10, t.enabled ? 1 : 0);
}

void add_threshold_routes(Core& core) {
    core.route("GET", "/api/v1/thresholds", Role::Read, [&core](Ctx& x) {
        auto c = core.pool.get();
        auto st = c->prepare(fmt::format("SELECT {} FROM thresholds ORDER BY id", kThresholdCols));
        json items = json::array();
        while (st.step()) items.push_back(threshold_json(st));
        x.reply(200, {{"items", items}, {"next_cursor", nullptr}});
    });
    core.route("POST", "/api/v1/thresholds", Role::Admin, [&core](Ctx& x) {
        auto c = core.pool.get();
        const Threshold t = validate_threshold(*c, parse_json_body(x.req.body));
        auto st = c->prepare(
            "INSERT INTO thresholds(name, scope, machine_id, tool_id, material_id, metric, flag, limit_value, severity, "
            "enabled, created_at) VALUES (?,?,?,?,?,?,?,?,?,?,?)");
        bind_threshold(st, t);
        st.bind(11, db::now_iso()).run();
        x.res.set_header("Location", fmt::format("/api/v1/thresholds/{}", c->last_insert_id()));
        x.reply(201, load_threshold(*c, c->last_insert_id()));
    });
    core.route("GET", "/api/v1/thresholds/{id}", Role::Read, [&core](Ctx& x) {
        auto c = core.pool.get();
        x.reply(200, load_threshold(*c, x.id()));
    });
    core.route("PUT", "/api/v1/thresholds/{id}", Role::Admin, [&core](Ctx& x) {
        auto c = core.pool.get();
        load_threshold(*c, x.id());
        const Threshold t = validate_threshold(*c, parse_json_body(x.req.body));
        auto st = c->prepare(
            "UPDATE thresholds SET name = ?, scope = ?, machine_id = ?, tool_id = ?, material_id = ?, metric = ?, "
            "flag = ?, limit_value = ?, severity = ?, enabled = ? WHERE id = ?");
        bind_threshold(st, t);
        st.bind(11, x.id()).run();
        x.reply(200, load_threshold(*c, x.id()));
    });
    core.route("DELETE", "/api/v1/thresholds/{id}", Role::Admin, [&core](Ctx& x) {
        auto c = core.pool.get();
        c->prepare("DELETE FROM thresholds WHERE id = ?").bind(1, x.id()).run();
        if (c->changes() == 0) not_found(fmt::format("threshold {} does not exist", x.id()));
        x.res.status = 204;
    });
}

// ---- alerts -------------------------------------------------------------------------------

void add_alert_query_routes(Core& core) {
    core.route("GET", "/api/v1/alerts", Role::Read, [&core](Ctx& x) {
        const auto limit = x.param_int("limit").value_or(100);
        if (limit < 1 || limit > 1000) bad_request("query parameter limit: must be 1..1000");
        const auto severity = x.param("severity");
        if (severity && !one_of(*severity, {"info", "warning", "critical"}))
            bad_request(fmt::format("query parameter severity: '{}' is not info, warning or critical", *severity));
        const auto acked = x.param_bool("acked");
        auto c = core.pool.get();
        auto st = c->prepare(
            "SELECT a.id, a.run_id, a.threshold_id, a.severity, a.body, a.created_at, a.acked_at, a.acked_by, a.ack_note, "
            "r.name, r.program, r.machine_id FROM alerts a JOIN runs r ON r.id = a.run_id "
            "WHERE (?1 IS NULL OR a.id < ?1) AND (?2 IS NULL OR a.run_id = ?2) AND (?3 IS NULL OR a.severity = ?3) "
            "AND (?4 IS NULL OR (a.acked_at IS NOT NULL) = ?4) AND (?5 IS NULL OR r.machine_id = ?5) "
            "AND (?6 IS NULL OR a.threshold_id = ?6) AND (?7 IS NULL OR a.created_at >= ?7) "
            "AND (?8 IS NULL OR a.created_at <= ?8) ORDER BY a.id DESC LIMIT ?9");
        st.bind(1, x.param_int("cursor")).bind(2, x.param_int("run_id")).bind(3, severity);
        if (acked)
            st.bind(4, *acked ? 1 : 0);
        else
            st.bind_null(4);
        st.bind(5, x.param_int("machine_id")).bind(6, x.param_int("threshold_id"));
        st.bind(7, x.param("since")).bind(8, x.param("until")).bind(9, limit + 1);
        json items = json::array();
        while (st.step()) items.push_back(alert_row_json(st));
        json next = nullptr;
        if (static_cast<std::int64_t>(items.size()) > limit) {
            items.erase(items.end() - 1);
            next = std::to_string(items.back()["id"].get<std::int64_t>());
        }
        x.reply(200, {{"items", items}, {"next_cursor", next}});
    });
    core.route("GET", "/api/v1/alerts/{id}", Role::Read, [&core](Ctx& x) {
        auto c = core.pool.get();
        json a = load_alert(*c, x.id());
        if (a.is_null()) not_found(fmt::format("alert {} does not exist", x.id()));
        x.reply(200, a);
    });
    core.route("POST", "/api/v1/alerts/{id}/ack", Role::Write, [&core](Ctx& x) {
        std::optional<std::string> note;
        if (!x.req.body.empty()) {
            const json b = parse_json_body(x.req.body);
            if (!b.is_object()) bad_request("body must be a JSON object ({\"note\": \"...\"}) or empty");
            if (b.contains("note")) {
                if (!b["note"].is_string()) bad_request("note: must be a string");
                note = b["note"].get<std::string>();
            }
        }
        auto c = core.pool.get();
        if (load_alert(*c, x.id()).is_null()) not_found(fmt::format("alert {} does not exist", x.id()));
        // Acknowledging twice keeps the first acknowledgement.
        c->prepare("UPDATE alerts SET acked_at = ?, acked_by = ?, ack_note = ? WHERE id = ? AND acked_at IS NULL")
            .bind(1, db::now_iso())
            .bind(2, x.actor)
            .bind(3, note)
            .bind(4, x.id())
            .run();
        x.reply(200, load_alert(*c, x.id()));
    });
}

// ---- webhooks -----------------------------------------------------------------------------

json webhook_json(const db::Stmt& st) {
    return {{"id", st.i64(0)},
            {"url", st.text(1)},
            {"has_secret", !st.is_null(2)},
            {"enabled", st.i64(3) != 0},
            {"created_at", st.text(4)}};
}

json load_webhook(db::Connection& c, std::int64_t id) {
    auto st = c.prepare("SELECT id, url, secret, enabled, created_at FROM webhooks WHERE id = ?");
    st.bind(1, id);
    if (!st.step()) not_found(fmt::format("webhook {} does not exist", id));
    return webhook_json(st);
}

struct Hook {
    std::string url;
    std::optional<std::string> secret;
    bool enabled = true;
};

Hook validate_hook(const json& b) {
    if (!b.is_object()) bad_request("body must be a JSON object");
    for (const auto& [k, v] : b.items())
        if (!one_of(k, {"url", "secret", "enabled"})) bad_request(fmt::format("{}: unknown key (expected url, secret, enabled)", k));
    Hook h;
    h.url = req_string(b, "url");
    std::string origin, path;
    std::string host;
    if (!split_http_url(h.url, &origin, &path, &host))
        bad_request(fmt::format("url: '{}' is not an http:// or https:// URL", h.url));
    if (std::string why = refused_webhook_host(host, false); !why.empty())
        bad_request(fmt::format("url: {}; webhooks may not target it", why));
    if (b.contains("secret")) {
        if (!b["secret"].is_string()) bad_request("secret: must be a string");
        h.secret = b["secret"].get<std::string>();
    }
    if (b.contains("enabled")) {
        if (!b["enabled"].is_boolean()) bad_request("enabled: must be true or false");
        h.enabled = b["enabled"].get<bool>();
    }
    return h;
}

void add_webhook_routes(Core& core) {
    core.route("GET", "/api/v1/webhooks", Role::Admin, [&core](Ctx& x) {
        auto c = core.pool.get();
        auto st = c->prepare("SELECT id, url, secret, enabled, created_at FROM webhooks ORDER BY id");
        json items = json::array();
        while (st.step()) items.push_back(webhook_json(st));
        x.reply(200, {{"items", items}, {"next_cursor", nullptr}});
    });
    core.route("POST", "/api/v1/webhooks", Role::Admin, [&core](Ctx& x) {
        const Hook h = validate_hook(parse_json_body(x.req.body));
        auto c = core.pool.get();
        c->prepare("INSERT INTO webhooks(url, secret, enabled, created_at) VALUES (?,?,?,?)")
            .bind(1, h.url)
            .bind(2, h.secret)
            .bind(3, h.enabled ? 1 : 0)
            .bind(4, db::now_iso())
            .run();
        x.res.set_header("Location", fmt::format("/api/v1/webhooks/{}", c->last_insert_id()));
        x.reply(201, load_webhook(*c, c->last_insert_id()));
    });
    core.route("GET", "/api/v1/webhooks/{id}", Role::Admin, [&core](Ctx& x) {
        auto c = core.pool.get();
        x.reply(200, load_webhook(*c, x.id()));
    });
    core.route("PUT", "/api/v1/webhooks/{id}", Role::Admin, [&core](Ctx& x) {
        const Hook h = validate_hook(parse_json_body(x.req.body));
        auto c = core.pool.get();
        c->prepare("UPDATE webhooks SET url = ?, secret = ?, enabled = ? WHERE id = ?")
            .bind(1, h.url)
            .bind(2, h.secret)
            .bind(3, h.enabled ? 1 : 0)
            .bind(4, x.id())
            .run();
        if (c->changes() == 0) not_found(fmt::format("webhook {} does not exist", x.id()));
        x.reply(200, load_webhook(*c, x.id()));
    });
    core.route("DELETE", "/api/v1/webhooks/{id}", Role::Admin, [&core](Ctx& x) {
        auto c = core.pool.get();
        c->prepare("DELETE FROM webhooks WHERE id = ?").bind(1, x.id()).run();
        if (c->changes() == 0) not_found(fmt::format("webhook {} does not exist", x.id()));
        x.res.status = 204;
    });
    core.route("GET", "/api/v1/webhooks/{id}/deliveries", Role::Admin, [&core](Ctx& x) {
        const auto limit = x.param_int("limit").value_or(100);
        if (limit < 1 || limit > 1000) bad_request("query parameter limit: must be 1..1000");
        auto c = core.pool.get();
        load_webhook(*c, x.id());
        auto st = c->prepare(
            "SELECT id, alert_id, state, attempts, next_attempt_unix, created_at, delivered_at FROM webhook_deliveries "
            "WHERE webhook_id = ?1 AND (?2 IS NULL OR id < ?2) ORDER BY id DESC LIMIT ?3");
        st.bind(1, x.id()).bind(2, x.param_int("cursor")).bind(3, limit + 1);
        auto at = c->prepare(
            "SELECT attempt, at, status, error, duration_ms FROM webhook_attempts WHERE delivery_id = ? ORDER BY attempt");
        json items = json::array();
        while (st.step()) {
            json attempts = json::array();
            at.reset();
            at.bind(1, st.i64(0));
            while (at.step())
                attempts.push_back({{"attempt", at.i64(0)},
                                    {"at", at.text(1)},
                                    {"status", at.is_null(2) ? json(nullptr) : json(at.i64(2))},
                                    {"error", at.is_null(3) ? json(nullptr) : json(at.text(3))},
                                    {"duration_ms", at.real(4)}});
            const std::string state = st.text(2);
            items.push_back({{"id", st.i64(0)},
                             {"alert_id", st.is_null(1) ? json(nullptr) : json(st.i64(1))},
                             {"state", state},
                             {"attempts", st.i64(3)},
                             {"next_attempt_unix", state == "pending" ? json(st.real(4)) : json(nullptr)},
                             {"created_at", st.text(5)},
                             {"delivered_at", st.is_null(6) ? json(nullptr) : json(st.text(6))},
                             {"log", attempts}});
        }
        json next = nullptr;
        if (static_cast<std::int64_t>(items.size()) > limit) {
            items.erase(items.end() - 1);
            next = std::to_string(items.back()["id"].get<std::int64_t>());
        }
        x.reply(200, {{"items", items}, {"next_cursor", next}});
    });
}

}  // namespace

void add_alert_routes(Core& core) {
    add_threshold_routes(core);
    add_alert_query_routes(core);
    add_webhook_routes(core);
}

}  // namespace cutload::server
