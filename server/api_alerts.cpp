// Routes: /api/v1/thresholds (rules), /api/v1/alerts (raised by finished runs, acknowledged by
// people) and /api/v1/webhooks (subscriptions and their delivery log).
#include "core.hpp"
#include "db/alerts.hpp"
#include "db/library.hpp"
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

db::ThresholdRule validate_threshold(db::Session& s, const json& b) {
    if (!b.is_object()) bad_request("body must be a JSON object");
    static const std::vector<std::string> keys{"name", "scope", "machine_id", "tool_id", "material_id", "metric",
                                               "flag", "limit", "severity", "enabled"};
    for (const auto& [k, v] : b.items())
        if (!one_of(k, keys)) bad_request(fmt::format("{}: unknown key (expected {})", k, join(keys)));
    db::ThresholdRule t;
    t.name = req_string(b, "name");
    t.scope = b.value("scope", "any");
    if (!one_of(t.scope, {"any", "machine", "tool", "material"}))
        bad_request(fmt::format("scope: '{}' is not any, machine, tool or material", t.scope));
    if (t.scope != "any") {
        const std::string key = t.scope + "_id";
        if (!b.contains(key) || !b[key].is_number_integer())
            bad_request(fmt::format("{}: required integer when scope is {}", key, t.scope));
        const std::int64_t id = b[key].get<std::int64_t>();
        const db::LibraryKind kind = t.scope == "machine" ? db::LibraryKind::Machine
                                   : t.scope == "tool"    ? db::LibraryKind::Tool
                                                          : db::LibraryKind::Material;
        if (!s.library().get(kind, id)) not_found(fmt::format("{} {}: no such {}", key, id, t.scope));
        (t.scope == "machine" ? t.machine_id : t.scope == "tool" ? t.tool_id : t.material_id) = id;
    }
    t.metric = req_string(b, "metric");
    if (!one_of(t.metric, threshold_metrics()))
        bad_request(fmt::format("metric: '{}' is not one of {}", t.metric, join(threshold_metrics())));
    if (t.metric == "flag") {
        t.flag = b.value("flag", "any");
        if (!one_of(*t.flag, known_flags())) bad_request(fmt::format("flag: '{}' is not one of {}", *t.flag, join(known_flags())));
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

json threshold_json(const db::ThresholdRecord& t) {
    json j{{"id", t.id},         {"name", t.name},         {"scope", t.scope},
           {"metric", t.metric}, {"severity", t.severity}, {"enabled", t.enabled},
           {"created_at", t.created_at}};
    if (t.machine_id) j["machine_id"] = *t.machine_id;
    if (t.tool_id) j["tool_id"] = *t.tool_id;
    if (t.material_id) j["material_id"] = *t.material_id;
    j["flag"] = or_null(t.flag);
    j["limit"] = or_null(t.limit);
    return j;
}

json load_threshold(db::Session& s, std::int64_t id) {
    const auto t = s.thresholds().get(id);
    if (!t) not_found(fmt::format("threshold {} does not exist", id));
    return threshold_json(*t);
}

void add_threshold_routes(Core& core) {
    core.route({"GET", "/api/v1/thresholds", Role::Read}, [&core](Ctx& x) {
        auto s = core.session();
        json items = json::array();
        for (const auto& t : s->thresholds().list()) items.push_back(threshold_json(t));
        x.reply(200, {{"items", items}, {"next_cursor", nullptr}});
    });
    core.route({"POST", "/api/v1/thresholds", Role::Admin, {}, Body::Json}, [&core](Ctx& x) {
        auto s = core.session();
        const db::ThresholdRule t = validate_threshold(*s, *x.json_body());
        const std::int64_t id = s->thresholds().create(t, db::now_iso());
        x.res.set_header("Location", fmt::format("/api/v1/thresholds/{}", id));
        x.reply(201, load_threshold(*s, id));
    });
    core.route({"GET", "/api/v1/thresholds/{id}", Role::Read, {path_id()}}, [&core](Ctx& x) {
        auto s = core.session();
        x.reply(200, load_threshold(*s, x.id()));
    });
    core.route({"PUT", "/api/v1/thresholds/{id}", Role::Admin, {path_id()}, Body::Json}, [&core](Ctx& x) {
        auto s = core.session();
        load_threshold(*s, x.id());
        const db::ThresholdRule t = validate_threshold(*s, *x.json_body());
        s->thresholds().update(x.id(), t);
        x.reply(200, load_threshold(*s, x.id()));
    });
    core.route({"DELETE", "/api/v1/thresholds/{id}", Role::Admin, {path_id()}}, [&core](Ctx& x) {
        auto s = core.session();
        if (!s->thresholds().remove(x.id())) not_found(fmt::format("threshold {} does not exist", x.id()));
        x.res.status = 204;
    });
}

// ---- alerts -------------------------------------------------------------------------------

// The page after `items` (sorted by id, newest first) when one more than `limit` came back.
json next_cursor(json& items, std::int64_t limit) {
    if (static_cast<std::int64_t>(items.size()) <= limit) return nullptr;
    items.erase(items.end() - 1);
    return std::to_string(items.back()["id"].get<std::int64_t>());
}

void add_alert_query_routes(Core& core) {
    core.route({"GET", "/api/v1/alerts", Role::Read,
                {query_int("cursor", "next_cursor of the previous page"),
                 query_int("limit", "page size").range(1, 1000).or_else(100),
                 query_int("run_id", "run"),
                 query_int("machine_id", "machine of the run"),
                 query_int("threshold_id", "rule"),
                 query_string("severity", "severity").one_of({"info", "warning", "critical"}),
                 query_bool("acked", "acknowledged or not"),
                 query_string("since", "ISO 8601 UTC"),
                 query_string("until", "ISO 8601 UTC")}},
               [&core](Ctx& x) {
                   db::AlertFilter f;
                   const std::int64_t limit = *x.param_int("limit");
                   f.limit = limit + 1;
                   f.before_id = x.param_int("cursor");
                   f.run_id = x.param_int("run_id");
                   f.machine_id = x.param_int("machine_id");
                   f.threshold_id = x.param_int("threshold_id");
                   f.severity = x.param("severity");
                   f.acked = x.param_bool("acked");
                   f.since = x.param("since");
                   f.until = x.param("until");
                   auto s = core.session();
                   json items = json::array();
                   for (const auto& a : s->alerts().list(f)) items.push_back(alert_json(a));
                   const json next = next_cursor(items, limit);
                   x.reply(200, {{"items", items}, {"next_cursor", next}});
               });
    core.route({"GET", "/api/v1/alerts/{id}", Role::Read, {path_id()}}, [&core](Ctx& x) {
        auto s = core.session();
        json a = load_alert(*s, x.id());
        if (a.is_null()) not_found(fmt::format("alert {} does not exist", x.id()));
        x.reply(200, a);
    });
    core.route({"POST", "/api/v1/alerts/{id}/ack", Role::Write, {path_id()}, Body::OptionalJson}, [&core](Ctx& x) {
        std::optional<std::string> note;
        if (const auto b = x.json_body()) {
            if (!b->is_object()) bad_request("body must be a JSON object ({\"note\": \"...\"}) or empty");
            if (b->contains("note")) {
                if (!(*b)["note"].is_string()) bad_request("note: must be a string");
                note = (*b)["note"].get<std::string>();
            }
        }
        auto s = core.session();
        if (load_alert(*s, x.id()).is_null()) not_found(fmt::format("alert {} does not exist", x.id()));
        // Acknowledging twice keeps the first acknowledgement.
        s->alerts().acknowledge(x.id(), db::now_iso(), x.actor, note);
        x.reply(200, load_alert(*s, x.id()));
    });
}

// ---- webhooks -----------------------------------------------------------------------------

json webhook_json(const db::WebhookRecord& w) {
    return {{"id", w.id}, {"url", w.url}, {"has_secret", w.secret.has_value()}, {"enabled", w.enabled}, {"created_at", w.created_at}};
}

json load_webhook(db::Session& s, std::int64_t id) {
    const auto w = s.webhooks().get(id);
    if (!w) not_found(fmt::format("webhook {} does not exist", id));
    return webhook_json(*w);
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

json delivery_json(const db::DeliveryRecord& d) {
    json log = json::array();
    for (const auto& a : d.log)
        log.push_back({{"attempt", a.attempt},
                       {"at", a.at},
                       {"status", or_null(a.http_status)},
                       {"error", or_null(a.error)},
                       {"duration_ms", a.duration_ms}});
    const bool pending = d.state == db::DeliveryState::Pending;
    return {{"id", d.id},
            {"alert_id", or_null(d.alert_id)},
            {"state", db::to_text(d.state)},
            {"attempts", d.attempts},
            {"next_attempt_unix", pending ? json(d.next_attempt_unix) : json(nullptr)},
            {"created_at", d.created_at},
            {"delivered_at", or_null(d.delivered_at)},
            {"log", log}};
}

void add_webhook_routes(Core& core) {
    core.route({"GET", "/api/v1/webhooks", Role::Admin}, [&core](Ctx& x) {
        auto s = core.session();
        json items = json::array();
        for (const auto& w : s->webhooks().list()) items.push_back(webhook_json(w));
        x.reply(200, {{"items", items}, {"next_cursor", nullptr}});
    });
    core.route({"POST", "/api/v1/webhooks", Role::Admin, {}, Body::Json}, [&core](Ctx& x) {
        const Hook h = validate_hook(*x.json_body());
        auto s = core.session();
        const std::int64_t id = s->webhooks().create(h.url, h.secret, h.enabled, db::now_iso());
        x.res.set_header("Location", fmt::format("/api/v1/webhooks/{}", id));
        x.reply(201, load_webhook(*s, id));
    });
    core.route({"GET", "/api/v1/webhooks/{id}", Role::Admin, {path_id()}}, [&core](Ctx& x) {
        auto s = core.session();
        x.reply(200, load_webhook(*s, x.id()));
    });
    core.route({"PUT", "/api/v1/webhooks/{id}", Role::Admin, {path_id()}, Body::Json}, [&core](Ctx& x) {
        const Hook h = validate_hook(*x.json_body());
        auto s = core.session();
        if (!s->webhooks().update(x.id(), h.url, h.secret, h.enabled))
            not_found(fmt::format("webhook {} does not exist", x.id()));
        x.reply(200, load_webhook(*s, x.id()));
    });
    core.route({"DELETE", "/api/v1/webhooks/{id}", Role::Admin, {path_id()}}, [&core](Ctx& x) {
        auto s = core.session();
        if (!s->webhooks().remove(x.id())) not_found(fmt::format("webhook {} does not exist", x.id()));
        x.res.status = 204;
    });
    core.route({"GET", "/api/v1/webhooks/{id}/deliveries", Role::Admin,
                {path_id(), query_int("cursor", "next_cursor of the previous page"),
                 query_int("limit", "page size").range(1, 1000).or_else(100)}},
               [&core](Ctx& x) {
                   const auto limit = *x.param_int("limit");
                   auto s = core.session();
                   load_webhook(*s, x.id());
                   json items = json::array();
                   for (const auto& d : s->webhooks().deliveries(x.id(), x.param_int("cursor"), limit + 1))
                       items.push_back(delivery_json(d));
                   const json next = next_cursor(items, limit);
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
