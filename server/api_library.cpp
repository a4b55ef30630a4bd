// Routes: /api/v1/machines, /api/v1/tools, /api/v1/materials (full CRUD, names unique).
#include "app/inputs.hpp"
#include "core.hpp"
#include "library.hpp"
#include "live_source.hpp"

#include <fmt/format.h>

namespace cutload::server {
namespace {

struct Kind {
    db::LibraryKind kind;
    const char* plural;     // the URL segment
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

// The machine's live source (docs/live.md): where POST /api/v1/live follows it when a request
// names the machine and no source. The key map is read when a live run starts.
json validate_live_source(const json& ls) {
    if (!ls.is_object()) throw ApiError(400, "bad_request", "live_source: must be an object with adapter, or agent and device");
    for (const auto& [k, v] : ls.items())
        if (k != "adapter" && k != "agent" && k != "device" && k != "key_map" && k != "sampling")
            throw ApiError(400, "bad_request", fmt::format("live_source.{}: unknown key", k));
    (void)live_source_address(ls, "live_source");
    if (ls.contains("key_map") && !ls["key_map"].is_object())
        throw ApiError(400, "bad_request", "live_source.key_map: must be a JSON object (a channel map, docs/formats.md)");
    if (ls.contains("sampling") && ls["sampling"] != "event" && ls["sampling"] != "polled")
        throw ApiError(400, "bad_request", "live_source.sampling: must be 'event' or 'polled'");
    return ls;
}

json validate_machine(const json& b) {
    only_keys(b, {"name", "spindle_power_kW", "spindle_torque_Nm", "max_feed_mm_min", "live_source"});
    json stored = {{"spindle_power_kW", positive(b, "spindle_power_kW")},
                   {"spindle_torque_Nm", positive(b, "spindle_torque_Nm")},
                   {"max_feed_mm_min", positive(b, "max_feed_mm_min")}};
    if (b.contains("live_source")) stored["live_source"] = validate_live_source(b["live_source"]);
    return stored;
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
    {db::LibraryKind::Machine, "machines", "machine", &validate_machine},
    {db::LibraryKind::Tool, "tools", "tool", &validate_tool},
    {db::LibraryKind::Material, "materials", "material", &validate_material},
};

std::string body_name(const json& b) {
    if (!b.is_object()) throw ApiError(400, "bad_request", "body must be a JSON object");
    if (!b.contains("name") || !b["name"].is_string() || b["name"].get<std::string>().empty())
        throw ApiError(400, "bad_request", "name: required non-empty string");
    auto n = b["name"].get<std::string>();
    if (n.size() > 200) throw ApiError(400, "bad_request", "name: longer than 200 characters");
    return n;
}

json item_json(const db::LibraryItem& item) {
    json j = json::parse(item.body_json);
    j["id"] = item.id;
    j["name"] = item.name;
    j["created_at"] = item.created_at;
    j["updated_at"] = item.updated_at;
    return j;
}

json get_one(db::Session& s, const Kind& k, std::int64_t id) {
    auto item = s.library().get(k.kind, id);
    if (!item) not_found(fmt::format("{} {} does not exist", k.singular, id));
    return item_json(*item);
}

[[noreturn]] void name_taken(const Kind& k, const std::string& name) {
    throw ApiError(409, "name_taken", fmt::format("a {} named '{}' already exists", k.singular, name));
}

void add_kind(Core& core, const Kind& k) {
    const std::string base = std::string("/api/v1/") + k.plural;
    core.route({"GET", base, Role::Read,
                {query_int("cursor", "next_cursor of the previous page").or_else(0),
                 query_int("limit", "page size").range(1, 1000).or_else(100),
                 query_string("name", "exact name")}},
               [&core, &k](Ctx& x) {
                   const auto limit = *x.param_int("limit");
                   auto s = core.session();
                   json items = json::array();
                   for (const auto& item : s->library().list(k.kind, *x.param_int("cursor"), x.param("name"), limit + 1))
                       items.push_back(item_json(item));
                   json next = nullptr;
                   if (static_cast<std::int64_t>(items.size()) > limit) {
                       items.erase(items.end() - 1);
                       next = std::to_string(items.back()["id"].get<std::int64_t>());
                   }
                   x.reply(200, {{"items", items}, {"next_cursor", next}});
               });
    core.route({"POST", base, Role::Write, {}, Body::Json}, [&core, &k](Ctx& x) {
        const json b = *x.json_body();
        const std::string name = body_name(b);
        const json stored = k.validate(b);
        auto s = core.session();
        const auto id = s->library().create(k.kind, name, stored.dump(), db::now_iso());
        if (!id) name_taken(k, name);
        x.res.set_header("Location", fmt::format("/api/v1/{}/{}", k.plural, *id));
        x.reply(201, get_one(*s, k, *id));
    });
    core.route({"GET", base + "/{id}", Role::Read, {path_id()}}, [&core, &k](Ctx& x) {
        auto s = core.session();
        x.reply(200, get_one(*s, k, x.id()));
    });
    core.route({"PUT", base + "/{id}", Role::Write, {path_id()}, Body::Json}, [&core, &k](Ctx& x) {
        const json b = *x.json_body();
        const std::string name = body_name(b);
        const json stored = k.validate(b);
        auto s = core.session();
        switch (s->library().update(k.kind, x.id(), name, stored.dump(), db::now_iso())) {
            case db::LibraryWrite::NameTaken: name_taken(k, name);
            case db::LibraryWrite::NotFound: not_found(fmt::format("{} {} does not exist", k.singular, x.id()));
            case db::LibraryWrite::Done: break;
        }
        x.reply(200, get_one(*s, k, x.id()));
    });
    core.route({"DELETE", base + "/{id}", Role::Write, {path_id()}}, [&core, &k](Ctx& x) {
        auto s = core.session();
        if (!s->library().remove(k.kind, x.id())) not_found(fmt::format("{} {} does not exist", k.singular, x.id()));
        x.res.status = 204;
    });
}

}  // namespace

std::optional<json> library_body(db::Session& s, db::LibraryKind kind, std::int64_t id) {
    const auto item = s.library().get(kind, id);
    if (!item) return std::nullopt;
    json j = json::parse(item->body_json);
    j["name"] = item->name;
    return j;
}

void add_library_routes(Core& c) {
    for (const auto& k : kKinds) add_kind(c, k);
}

}  // namespace cutload::server
