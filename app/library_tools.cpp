#include "app/library_tools.hpp"

#include <fmt/format.h>

namespace cutload::app {

namespace {

using nlohmann::json;

// The per-tool limits a table entry may carry; a library tool's rapid feed is the machine's and
// stays out of the table, as force_model's parser demands.
constexpr const char* kToolLimitKeys[] = {"force_N", "torque_Nm", "power_kW", "chip_mm", "bending_MPa"};

}  // namespace

UnknownLibraryTool::UnknownLibraryTool(std::string key, std::int64_t id)
    : InputError(std::move(key), fmt::format("no library tool has id {}", id)), id_(id) {}

json resolve_library_tools(json spec, const LibraryToolLookup& lookup, std::vector<LibraryToolRef>* refs) {
    if (!spec.is_object() || !spec.contains("tools") || !spec["tools"].is_array()) return spec;
    json& table = spec["tools"];
    for (std::size_t k = 0; k < table.size(); ++k) {
        json& entry = table[k];
        if (!entry.is_object() || !entry.contains("tool_id")) continue;
        const std::string key = fmt::format("tools[{}].tool_id", k);
        const json& id_json = entry["tool_id"];
        if (!id_json.is_number_integer()) throw InputError(key, "must be an integer id of a library tool");
        const auto id = id_json.get<std::int64_t>();
        for (const auto& [field, value] : entry.items())
            if (field != "tool_id" && field != "number" && field != "limits")
                throw InputError(key, fmt::format("give either the tool's fields or tool_id, not both (the entry has "
                                                  "'{}')",
                                                  field));
        const std::optional<json> stored = lookup(id);
        if (!stored || !stored->contains("tool") || !(*stored)["tool"].is_object()) throw UnknownLibraryTool(key, id);

        json resolved = (*stored)["tool"];
        if (entry.contains("number")) resolved["number"] = entry["number"];
        json limits = json::object();
        if (const auto l = stored->find("limits"); l != stored->end() && l->is_object())
            for (const char* name : kToolLimitKeys)
                if (const auto v = l->find(name); v != l->end() && v->is_number() && v->get<double>() > 0)
                    limits[name] = *v;
        if (entry.contains("limits") && entry["limits"].is_object())
            for (const auto& [name, value] : entry["limits"].items()) limits[name] = value;
        else if (entry.contains("limits") && !entry["limits"].is_null())
            limits = entry["limits"];   // not an object: the parser names tools[k].limits
        if (!limits.empty()) resolved["limits"] = std::move(limits);

        if (refs && entry.contains("number") && entry["number"].is_number_integer())
            refs->push_back({entry["number"].get<int>(), id});
        entry = std::move(resolved);
    }
    return spec;
}

}  // namespace cutload::app
