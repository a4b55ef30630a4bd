// Routes: /api/v1/machines, /api/v1/tools, /api/v1/materials (full CRUD, names unique).
#include "app/inputs.hpp"
#include "core.hpp"
#include "library.hpp"

#include <fmt/format.h>

namespace cutload::server {
namespace {

struct Kind {
    const char* table;      // also the URL segment
    const char* singular;
    // Validates a request body and returns what is stored (without name and timestamps).
    json (*validate)(const json& body);
};

double positive(const json& body, const char* key) {
    if (!body.contains(key)) throw ApiError(400, "bad_request", fmt::format("{}: required", key));
    const json& v = body[key];
    if (!v.is_number() || v.get<double>() <= 0)
        throw ApiError(400, "bad_request", fmt::format("{}: must be a number > 0", key));
    return v.get<double>();
}

void only_keys(const json& body, std::initializer_list<const char*> keys) {
    for (const auto& [k, v] : body.items()) {
        bool known = false;
        for (const char* a : keys) known = known || k == a;
        if (!known) throw ApiError(400, "bad_request", fmt::format("{}: unknown key", k));
    }
}

json validate_machine(const json& b) {
    only_keys(b, {"name", "spindle_power_kW", "spindle_torque_Nm", "max_feed_mm_min"});
    return {{"spindle_power_kW", positive(b, "spindle_power_kW")},
            {"spindle_torque_Nm", positive(b, "spindle_torque_Nm")},
            {"max_feed_mm_min", positive(b, "max_feed_mm_min")}};
}

json validate_tool(const json& b) {
    only_keys(b, {"name", "tool", "limits"});
    if (!b.contains("tool") || !b["tool"].is_object()) throw ApiError(400, "bad_spec", "tool: required object");
    json spec = app::probe_spec();
    spec["tool"] = b["tool"];
    if (b.contains("limits")) spec["limits"] = b["limits"];
    force_model::parse_run_spec(spec);
    return {{"tool", b["tool"]}, {"limits", b.value("limits", json::object())}};
}

json validate_material(const json& b) {
    try {
        app::parse_material(b);
    } catch (const force_model::SpecError& e) {
        // The engine names keys under "material."; the body is the material itself.
        std::string msg = e.what();
        if (msg.rfind("material.", 0) == 0) msg = msg.substr(9);
        throw ApiError(400, "bad_spec", msg);
    }
    json stored = b;
    stored.erase("name");
    return stored;
}

const Kind kKinds[] = {
    {"machines", "machine", &validate_machine},
    {"tools", "tool", &validate_tool},
    {"materials", "material", &validate_material},
};

std::string body_name(const json& b) {
    if (!b.is_object()) throw ApiError(400, "bad_request", "body must be a JSON object");
    if (!b.contains("name") || !b["name"].is_string() || b["name"].get<std::string>().empty())
        throw ApiError(400, "bad_request", "name: required non-empty string");
    auto n = b["name"].get<std::string>();
    if (n.size() > 200) throw ApiError(400, "bad_request", "name: longer than 200 characters");
    return n;
}

json row_json(const db::Stmt& st) {
    json j = json::parse(st.text(2));
    j["id"] = st.i64(0);
    j["name"] = st.text(1);
    j["created_at"] = st.text(3);
    j["updated_at"] = st.text(4);
    return j;
}

json get_one(db::Connection& c, const Kind& k, std::int64_t id) {
    auto st = c.prepare(fmt::format("SELECT id, name, body, created_at, updated_at FROM {} WHERE id = ?", k.table));
    st.bind(1, id);
    if (!st.step()) not_found(fmt::format("{} {} does not exist", k.singular, id));
    return row_json(st);
}

[[noreturn]] void name_taken(const Kind& k, const std::string& name) {
    throw ApiError(409, "name_taken", fmt::format("a {} named '{}' already exists", k.singular, name));
}

void add_kind(Core& core, const Kind& k) {
    const std::string base = std::string("/api/v1/") + k.table;
    core.route("GET", base, Role::Read, [&core, &k](Ctx& x) {
        const auto limit = x.param_int("limit").value_or(100);
        if (limit < 1 || limit > 1000) bad_request("query parameter limit: must be 1..1000");
        const auto cursor = x.param_int("cursor").value_or(0);
        auto c = core.pool.get();
        auto st = c->prepare(fmt::format(
            "SELECT id, name, body, created_at, updated_at FROM {} WHERE id > ? AND (? IS NULL OR name = ?) "
            "ORDER BY id LIMIT ?",
            k.table));
        st.bind(1, cursor).bind(2, x.param("name")).bind(3, x.param("name")).bind(4, limit + 1);
        json items = json::array();
        while (st.step()) items.push_back(row_json(st));
        json next = nullptr;
        if (static_cast<std::int64_t>(items.size()) > limit) {
            items.erase(items.end() - 1);
            next = std::to_string(items.back()["id"].get<std::int64_t>());
        }
        x.reply(200, {{"items", items}, {"next_cursor", next}});
    });
    core.route("POST", base, Role::Write, [&core, &k](Ctx& x) {
        const json b = parse_json_body(x.req.body);
        const std::string name = body_name(b);
        const json stored = k.validate(b);
        auto c = core.pool.get();
        const std::string now = db::now_iso();
        try {
            c->prepare(fmt::format("INSERT INTO {}(name, body, created_at, updated_at) VALUES (?,?,?,?)", k.table))
                .bind(1, name)
                .bind(2, stored.dump())
                .bind(3, now)
                .bind(4, now)
                .run();
        } catch (const db::Error& e) {
            if (e.is_constraint()) name_taken(k, name);
            throw;
        }
        x.res.set_header("Location", fmt::format("/api/v1/{}/{}", k.table, c->last_insert_id()));
        x.reply(201, get_one(*c, k, c->last_insert_id()));
    });
    core.route("GET", base + "/{id}", Role::Read, [&core, &k](Ctx& x) {
        auto c = core.pool.get();
        x.reply(200, get_one(*c, k, x.id()));
    });
    core.route("PUT", base + "/{id}", Role::Write, [&core, &k](Ctx& x) {
        const json b = parse_json_body(x.req.body);
        const std::string name = body_name(b);
        const json stored = k.validate(b);
        auto c = core.pool.get();
        try {
            c->prepare(fmt::format("UPDATE {} SET name = ?, body = ?, updated_at = ? WHERE id = ?", k.table))
                .bind(1, name)
                .bind(2, stored.dump())
                .bind(3, db::now_iso())
                .bind(4, x.id())
                .run();
        } catch (const db::Error& e) {
            if (e.is_constraint()) name_taken(k, name);
            throw;
        }
        if (c->changes() == 0) not_found(fmt::format("{} {} does not exist", k.singular, x.id()));
        x.reply(200, get_one(*c, k, x.id()));
    });
    core.route("DELETE", base + "/{id}", Role::Write, [&core, &k](Ctx& x) {
        auto c = core.pool.get();
        c->prepare(fmt::format("DELETE FROM {} WHERE id = ?", k.table)).bind(1, x.id()).run();
        if (c->changes() == 0) not_found(fmt::format("{} {} does not exist", k.singular, x.id()));
        x.res.status = 204;
    });
}

}  // namespace

std::optional<json> library_body(db::Connection& c, const char* table, std::int64_t id) {
    auto st = c.prepare(fmt::format("SELECT name, body FROM {} WHERE id = ?", table));
    st.bind(1, id);
    if (!st.step()) return std::nullopt;
    json j = json::parse(st.text(1));
    j["name"] = st.text(0);
    return j;
}

void add_library_routes(Core& c) {
    for (const auto& k : kKinds) add_kind(c, k);
}

}  // namespace cutload::server
