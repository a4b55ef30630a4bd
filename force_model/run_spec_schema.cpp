// The run spec's JSON Schema, derived from the parser: reference specs (one per tool shape, every
// optional section present) are parsed with a recorder on, and every key read becomes a property.
// The service publishes it (OpenAPI components RunSpec, Tool, NumberedTool) and the web page
// builds its spec form from it, so a key added to the parser reaches both without a second list.
// Only the words (titles) are kept here, since the parser has none; units come from the key names.
#include "force_model/force_model.hpp"
#include "run_spec_reads.hpp"

#include <algorithm>
#include <map>
#include <set>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace cutload::force_model {
namespace {

using nlohmann::json;

// Titles by the key's last one or two segments (the more specific first). A key the parser reads
// without a title here is a programming error: run_spec_schema() throws and the tests catch it.
const std::map<std::string, std::string>& titles() {
    static const std::map<std::string, std::string> t = {
        {"tool", "Tool"}, {"tools", "Tool table"}, {"number", "T number"},
        {"shape", "Shape"}, {"diameter_mm", "Diameter"}, {"flutes", "Flutes"}, {"helix_deg", "Helix"},
        {"corner_radius_mm", "Corner radius"}, {"point_angle_deg", "Point angle"},
        {"tip_diameter_mm", "Tip diameter"}, {"taper_deg", "Taper per side"}, {"barrel_radius_mm", "Barrel radius"},
        {"tip_radius_mm", "Tip ball radius"}, {"flute_length_mm", "Flute length"}, {"stickout_mm", "Stick-out"},
        {"holder", "Holder"}, {"holder.diameter_mm", "Holder diameter"}, {"holder.length_mm", "Holder length"},
        {"material", "Material"}, {"name", "Material name"},
        {"Ktc_N_mm2", "Ktc"}, {"Krc_N_mm2", "Krc"}, {"Kac_N_mm2", "Kac"},
        {"Kte_N_mm", "Kte"}, {"Kre_N_mm", "Kre"}, {"Kae_N_mm", "Kae"},
        {"stock", "Stock"}, {"box_mm", "Stock box"}, {"box_mm.min", "Stock min x, y, z"},
        {"box_mm.max", "Stock max x, y, z"},
        {"setup", "Setup"}, {"offset_mm", "Offset x, y, z"},
        {"limits", "Limits"}, {"force_N", "Force"}, {"torque_Nm", "Torque"}, {"power_kW", "Power"},
        {"chip_mm", "Chip thickness"}, {"bending_MPa", "Bending"}, {"rapid_feed_mm_min", "Rapid feed"},
        {"holder_clearance_mm", "Holder clearance"},
        {"resolution", "Resolution"}, {"angle_step_deg", "Angle step"}, {"axial_step_mm", "Axial step"},
        {"grid_mm", "Grid"},
    };
    return t;
}

// Whole numbers although JSON reads them as numbers.
const std::set<std::string> kIntegerKeys = {"flutes", "number"};

// The unit a key's name ends with, as the page writes it ("" for none).
std::string unit_of(const std::string& key) {
    static const std::pair<const char*, const char*> suffixes[] = {
        {"_N_mm2", "N/mm²"}, {"_N_mm", "N/mm"}, {"_mm_min", "mm/min"}, {"_mm", "mm"}, {"_deg", "deg"},
        {"_Nm", "N·m"},      {"_kW", "kW"},     {"_MPa", "MPa"},       {"_N", "N"}};
    for (const auto& [suffix, unit] : suffixes) {
        const std::string s = suffix;
        if (key.size() > s.size() && key.compare(key.size() - s.size(), s.size(), s) == 0) return unit;
    }
    return "";
}

std::vector<std::string> split_path(const std::string& path) {
    std::vector<std::string> parts;
    std::string cur;
    for (char c : path) {
        if (c == '.') {
            parts.push_back(cur);
            cur.clear();
        } else {
            cur += c;
        }
    }
    parts.push_back(cur);
    return parts;
}

std::string bare(const std::string& segment) {
    return segment.size() > 2 && segment.ends_with("[]") ? segment.substr(0, segment.size() - 2) : segment;
}

std::string title_of(const std::vector<std::string>& parts) {
    const auto& t = titles();
    if (parts.size() >= 2) {
        auto it = t.find(bare(parts[parts.size() - 2]) + "." + parts.back());
        if (it != t.end()) return it->second;
    }
    auto it = t.find(bare(parts.back()));
    if (it == t.end()) throw std::logic_error("run spec schema: no title for the key " + parts.back());
    return it->second;
}

json tool_json(const char* shape) {
    const std::string s = shape;
    json tool = {{"shape", s}, {"diameter_mm", 10}, {"flutes", 2}, {"helix_deg", 30},
                 {"flute_length_mm", 30}, {"stickout_mm", 40}, {"holder", {{"diameter_mm", 32}, {"length_mm", 60}}}};
    if (s == "bull") tool["corner_radius_mm"] = 1;
    if (s == "drill") tool["point_angle_deg"] = 118;
    if (s == "chamfer") {
        tool["point_angle_deg"] = 90;
        tool["tip_diameter_mm"] = 2;
    }
    if (s == "barrel") {
        tool["barrel_radius_mm"] = 50;
        tool["tip_radius_mm"] = 1;
    }
    return tool;
}

// Every optional section present, so that every key the parser can read is read.
json reference_spec(const char* shape) {
    json numbered = tool_json(shape);
    numbered["number"] = 1;
    numbered["limits"] = {{"force_N", 500}, {"torque_Nm", 10}, {"power_kW", 5}, {"chip_mm", 0.2}, {"bending_MPa", 300}};
    return {{"tool", tool_json(shape)},
            {"tools", json::array({numbered})},
            {"material", {{"name", "reference"}, {"Ktc_N_mm2", 800}, {"Krc_N_mm2", 300}, {"Kac_N_mm2", 100},
                          {"Kte_N_mm", 20}, {"Kre_N_mm", 15}, {"Kae_N_mm", 2}}},
            {"stock", {{"box_mm", {{"min", {0, 0, -10}}, {"max", {50, 50, 0}}}}}},
            {"setup", {{"offset_mm", {0, 0, 0}}}},
            {"limits", {{"force_N", 500}, {"torque_Nm", 10}, {"power_kW", 5}, {"chip_mm", 0.2},
                        {"bending_MPa", 300}, {"rapid_feed_mm_min", 10000}}},
            {"resolution", {{"angle_step_deg", 2}, {"axial_step_mm", 0.5}, {"grid_mm", 0.5}}}};
}

struct Merged {
    std::string type;
    bool required = true;
    std::vector<std::string> options;
    std::set<std::string> shapes;            // tool shapes under which the parser reads the key
    std::set<std::string> required_shapes;   // ... and requires it
    std::size_t order = 0;
};

json leaf_schema(const std::string& key, const Merged& m) {
    json s;
    if (m.type == "vec3") {
        s = {{"type", "array"}, {"items", {{"type", "number"}}}, {"minItems", 3}, {"maxItems", 3}};
    } else if (m.type == "number") {
        s = {{"type", kIntegerKeys.count(key) ? "integer" : "number"}};
    } else if (m.type == "string") {
        s = {{"type", "string"}};
        if (!m.options.empty()) s["enum"] = m.options;
    } else if (m.type == "array") {
        s = {{"type", "array"}, {"minItems", 1}, {"items", {{"type", "object"}, {"additionalProperties", false}}}};
    } else {
        s = {{"type", "object"}, {"additionalProperties", false}, {"properties", json::object()}};
    }
    const std::string unit = unit_of(key);
    if (!unit.empty()) s["x-unit"] = unit;
    return s;
}

// The object schema that holds the last segment of `parts`, created along the way.
json& parent_of(json& root, const std::vector<std::string>& parts) {
    json* node = &root;
    for (std::size_t i = 0; i + 1 < parts.size(); ++i) {
        json& child = (*node)["properties"][bare(parts[i])];
        node = parts[i].ends_with("[]") ? &child["items"] : &child;
    }
    return *node;
}

}  // namespace

nlohmann::json run_spec_schema() {
    const std::vector<std::string> shapes = tool_shape_names();
    std::map<std::string, Merged> keys;
    std::size_t order = 0;
    for (const std::string& name : shapes) {
        const char* shape = name.c_str();
        for (const KeyRead& r : keys_read(reference_spec(shape))) {
            auto [it, fresh] = keys.try_emplace(r.path);
            Merged& m = it->second;
            if (fresh) {
                m.type = r.type;
                m.order = order++;
            }
            m.required = m.required && r.required;   // required only where every read requires it
            if (!r.options.empty()) m.options = r.options;
            m.shapes.insert(shape);
            if (r.required) m.required_shapes.insert(shape);
        }
    }
    std::vector<std::pair<std::string, Merged>> ordered(keys.begin(), keys.end());
    std::sort(ordered.begin(), ordered.end(), [](const auto& a, const auto& b) { return a.second.order < b.second.order; });

    json root = {{"type", "object"}, {"additionalProperties", false}, {"properties", json::object()}};
    for (const auto& [path, m] : ordered) {
        const std::vector<std::string> parts = split_path(path);
        const std::string key = bare(parts.back());
        json& parent = parent_of(root, parts);
        json leaf = leaf_schema(key, m);
        leaf["title"] = title_of(parts);
        const bool tool_key = parts.size() >= 2 && (parts[0] == "tool" || parts[0] == "tools[]");
        if (tool_key && m.shapes.size() < shapes.size())
            leaf["x-tool-shapes"] = std::vector<std::string>(m.shapes.begin(), m.shapes.end());
        // Required for some shapes only (a bull's corner radius, a cone's point angle): JSON
        // Schema's required list cannot say so.
        const bool some_shapes = tool_key && !m.required_shapes.empty() && m.required_shapes.size() < shapes.size();
        if (some_shapes)
            leaf["x-required-shapes"] = std::vector<std::string>(m.required_shapes.begin(), m.required_shapes.end());
        json& slot = parent["properties"][key];
        // A container met first as a parent keeps what it gathered.
        if (slot.is_object() && slot.contains("properties")) leaf["properties"] = slot["properties"];
        if (slot.is_object() && slot.contains("items") && leaf.contains("items")) leaf["items"].update(slot["items"]);
        slot = leaf;
        if (m.required && m.shapes.size() == shapes.size()) parent["required"].push_back(key);
    }
    root["title"] = "Run spec";
    root["description"] =
        "RUN.json (docs/run_spec.md), derived from the parser: tool or tools (at least one), material, stock, "
        "setup, limits, resolution. x-unit is the unit a key's name ends with; x-tool-shapes lists the tool "
        "shapes a key applies to, x-required-shapes those that require it. Unknown keys and "
        "bad values are 400 bad_spec naming the key, e.g. tools[2].diameter_mm.";
    return root;
}

}  // namespace cutload::force_model
