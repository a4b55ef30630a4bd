// The published run-spec schema against the parser, both ways: what the schema lists the parser
// reads (required keys are required, optional ones optional, nothing else accepted), and what the
// parser reads or writes the schema lists. The specs here are written by hand, not taken from the
// schema's own reference specs.
#include "force_model/force_model.hpp"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <set>
#include <string>
#include <vector>

using cutload::force_model::parse_run_spec;
using cutload::force_model::run_spec_schema;
using cutload::force_model::SpecError;
using cutload::force_model::to_json;
using nlohmann::json;

namespace {

// A shop's full spec for a shape: every section and every optional key the shape allows.
json full_spec(const std::string& shape) {
    json tool = {{"shape", shape},        {"diameter_mm", 12},       {"flutes", 3},
                 {"helix_deg", 35},       {"flute_length_mm", 26},   {"stickout_mm", 45},
                 {"holder", {{"diameter_mm", 40}, {"length_mm", 70}}}};
    if (shape == "flat") tool["corner_radius_mm"] = 0;
    if (shape == "ball") tool["corner_radius_mm"] = 6;
    if (shape == "bull") tool["corner_radius_mm"] = 1.5;
    if (shape == "flat" || shape == "ball" || shape == "bull") tool["taper_deg"] = 1.5;   // a draft-wall tool
    if (shape == "drill") tool["point_angle_deg"] = 140;
    if (shape == "chamfer") {
        tool["point_angle_deg"] = 90;
        tool["tip_diameter_mm"] = 1;
    }
    if (shape == "barrel") {   // widest point 2 + sqrt(448) = 23.2 mm above the tip, below the flutes' end
        tool["barrel_radius_mm"] = 60;
        tool["tip_radius_mm"] = 2;
    }
    json t7 = tool;
    t7["number"] = 7;
    t7["limits"] = {{"force_N", 900}, {"torque_Nm", 12}, {"power_kW", 7.5}, {"chip_mm", 0.25}, {"bending_MPa", 350}};
    return {{"tool", tool},
            {"tools", json::array({t7})},
            {"material", {{"name", "S50C"}, {"Ktc_N_mm2", 2100}, {"Krc_N_mm2", 750}, {"Kac_N_mm2", -60},
                          {"Kte_N_mm", 35}, {"Kre_N_mm", 40}, {"Kae_N_mm", 0.5}}},
            {"stock", {{"box_mm", {{"min", {-20, -20, -40}}, {"max", {120, 80, 0}}}}}},
            {"setup", {{"offset_mm", {-350.5, 120.25, 410}}}},
            {"limits", {{"force_N", 1200}, {"torque_Nm", 20}, {"power_kW", 11}, {"chip_mm", 0.3},
                        {"bending_MPa", 400}, {"rapid_feed_mm_min", 24000}}},
            {"resolution", {{"angle_step_deg", 3}, {"axial_step_mm", 0.25}, {"grid_mm", 0.4}}}};
}

const std::vector<std::string> kShapes = {"flat", "ball", "bull", "drill", "chamfer", "barrel"};

std::string error_of(const json& j) {
    try {
        parse_run_spec(j);
    } catch (const SpecError& e) {
        return e.what();
    }
    return "";
}

// A property of the schema with where it sits in a spec.
struct Property {
    std::vector<std::string> path;   // JSON keys, "tools" then index 0 for the table's items
    std::string dotted;              // tools[0].limits.force_N
    json schema;
    bool required = false;           // in its parent's required list
};

void collect(const json& object_schema, std::vector<std::string> prefix, const std::string& dotted,
             std::vector<Property>& out) {
    const json required = object_schema.value("required", json::array());
    for (const auto& [key, s] : object_schema.at("properties").items()) {
        Property p{prefix, dotted.empty() ? key : dotted + "." + key, s, false};
        p.path.push_back(key);
        for (const auto& r : required) p.required = p.required || r == key;
        out.push_back(p);
        if (s.value("type", "") == "object" && s.contains("properties")) collect(s, p.path, p.dotted, out);
        if (s.value("type", "") == "array" && s.contains("items") && s["items"].contains("properties")) {
            std::vector<std::string> item = p.path;
            item.push_back("0");
            collect(s["items"], item, p.dotted + "[0]", out);
        }
    }
}

json& at(json& j, const std::vector<std::string>& path, std::size_t n) {
    json* node = &j;
    for (std::size_t i = 0; i < n; ++i) node = path[i] == "0" ? &(*node)[0] : &(*node)[path[i]];
    return *node;
}

bool applies(const Property& p, const std::string& shape) {
    if (!p.schema.contains("x-tool-shapes")) return true;
    for (const auto& s : p.schema["x-tool-shapes"])
        if (s == shape) return true;
    return false;
}

// Every key path of a JSON value, arrays' items as [0].
void keys_of(const json& j, const std::string& dotted, std::set<std::string>& out) {
    if (j.is_object()) {
        for (const auto& [k, v] : j.items()) {
            const std::string d = dotted.empty() ? k : dotted + "." + k;
            out.insert(d);
            keys_of(v, d, out);
        }
    } else if (j.is_array() && !j.empty() && j[0].is_object()) {
        keys_of(j[0], dotted + "[0]", out);
    }
}

}  // namespace

TEST_CASE("run spec schema: every shop spec parses, and every key in it is in the schema", "[spec][schema]") {
    std::vector<Property> props;
    collect(run_spec_schema(), {}, "", props);
    std::set<std::string> listed;
    for (const Property& p : props) listed.insert(p.dotted);
    for (const std::string& shape : kShapes) {
        INFO(shape);
        const json spec = full_spec(shape);
        REQUIRE(error_of(spec).empty());
        std::set<std::string> used;
        keys_of(spec, "", used);
        for (const std::string& k : used) {
            INFO(k);
            CHECK(listed.count(k) == 1);
        }
        // What the writer writes back is read by the same parser, so it is in the schema too.
        std::set<std::string> written;
        keys_of(to_json(parse_run_spec(spec)), "", written);
        for (const std::string& k : written) {
            INFO("written: " << k);
            CHECK(listed.count(k) == 1);
        }
    }
}

TEST_CASE("run spec schema: each required key is required by the parser, each optional one is not", "[spec][schema]") {
    std::vector<Property> props;
    collect(run_spec_schema(), {}, "", props);
    REQUIRE(props.size() > 40);
    int required_checked = 0, optional_checked = 0;
    for (const std::string& shape : kShapes) {
        for (const Property& p : props) {
            if (!applies(p, shape)) continue;
            json spec = full_spec(shape);
            json& parent = at(spec, p.path, p.path.size() - 1);
            if (!parent.contains(p.path.back())) continue;   // an optional key this shape's spec leaves out
            parent.erase(p.path.back());
            const std::string err = error_of(spec);
            INFO(shape << ": without " << p.dotted << ": " << err);
            bool required = p.required;
            for (const auto& r : p.schema.value("x-required-shapes", json::array())) required = required || r == shape;
            if (required) {
                CHECK(err.rfind(p.dotted + ":", 0) == 0);
                ++required_checked;
            } else if (!(p.dotted == "tool" || p.dotted == "tools")) {
                CHECK(err.empty());
                ++optional_checked;
            }
        }
    }
    // The spec has both kinds in every section; a schema that marked all or none would fail here.
    CHECK(required_checked > 60);
    CHECK(optional_checked > 60);
    // At least one of tool and tools: the schema lists both as optional, the parser needs one.
    json neither = full_spec("flat");
    neither.erase("tool");
    neither.erase("tools");
    CHECK(error_of(neither).rfind("tool: required key is missing", 0) == 0);
}

TEST_CASE("run spec schema: a key the schema does not list is refused wherever it is put", "[spec][schema]") {
    std::vector<Property> props;
    collect(run_spec_schema(), {}, "", props);
    // Every object the schema describes, plus the root.
    std::vector<Property> objects{{{}, "", run_spec_schema(), false}};
    for (const Property& p : props)
        if (p.schema.value("type", "") == "object") objects.push_back(p);
        else if (p.schema.value("type", "") == "array" && p.schema["items"].contains("properties"))
            objects.push_back({[&] { auto v = p.path; v.push_back("0"); return v; }(), p.dotted + "[0]", p.schema["items"]});
    for (const Property& o : objects) {
        CHECK(o.schema.value("additionalProperties", true) == false);
        json spec = full_spec("chamfer");
        at(spec, o.path, o.path.size())["coolant_bar"] = 70;
        const std::string where = o.dotted.empty() ? "coolant_bar" : o.dotted + ".coolant_bar";
        INFO(where);
        CHECK(error_of(spec) == where + ": unknown key");
    }
}

TEST_CASE("run spec schema: shapes, shape-only keys, types, units and titles", "[spec][schema]") {
    const json s = run_spec_schema();
    const json& tool = s["properties"]["tool"];
    CHECK(tool["properties"]["shape"]["enum"] == json(kShapes));
    for (const std::string& shape : kShapes) CHECK(error_of(full_spec(shape)).empty());
    json oval = full_spec("flat");
    oval["tool"]["shape"] = "oval";
    CHECK(error_of(oval).find("tool.shape: expected one of \"flat\", \"ball\", \"bull\", \"drill\", \"chamfer\", \"barrel\"") == 0);

    CHECK(tool["properties"]["point_angle_deg"]["x-tool-shapes"] == json({"chamfer", "drill"}));
    CHECK(tool["properties"]["point_angle_deg"]["x-required-shapes"] == json({"chamfer", "drill"}));
    CHECK(tool["properties"]["tip_diameter_mm"]["x-tool-shapes"] == json({"chamfer"}));
    CHECK_FALSE(tool["properties"]["tip_diameter_mm"].contains("x-required-shapes"));
    CHECK(tool["properties"]["corner_radius_mm"]["x-required-shapes"] == json({"bull"}));
    CHECK(tool["properties"]["corner_radius_mm"]["x-tool-shapes"] == json({"ball", "bull", "chamfer", "drill", "flat"}));
    for (const char* key : {"barrel_radius_mm", "tip_radius_mm"}) {
        INFO(key);
        CHECK(tool["properties"][key]["x-tool-shapes"] == json({"barrel"}));
        CHECK(tool["properties"][key]["x-required-shapes"] == json({"barrel"}));
        CHECK(tool["properties"][key]["x-unit"] == "mm");
    }
    CHECK(tool["properties"]["barrel_radius_mm"]["title"] == "Barrel radius");
    CHECK_FALSE(tool["properties"]["diameter_mm"].contains("x-tool-shapes"));
    CHECK(tool["properties"]["taper_deg"]["x-tool-shapes"] == json({"ball", "bull", "flat"}));
    CHECK_FALSE(tool["properties"]["taper_deg"].contains("x-required-shapes"));
    CHECK(tool["properties"]["taper_deg"]["x-unit"] == "deg");
    CHECK(tool["properties"]["taper_deg"]["title"] == "Taper per side");
    // The same tool fields in the table's items.
    const json& item = s["properties"]["tools"]["items"];
    CHECK(item["properties"]["point_angle_deg"]["x-tool-shapes"] == json({"chamfer", "drill"}));
    CHECK(item["properties"]["number"]["type"] == "integer");
    CHECK(item["required"].size() == tool["required"].size() + 1);

    CHECK(tool["properties"]["flutes"]["type"] == "integer");
    CHECK(tool["properties"]["diameter_mm"]["x-unit"] == "mm");
    CHECK(tool["properties"]["holder"]["properties"]["diameter_mm"]["title"] == "Holder diameter");
    CHECK(s["properties"]["material"]["properties"]["Ktc_N_mm2"]["x-unit"] == "N/mm²");
    CHECK(s["properties"]["material"]["properties"]["Kte_N_mm"]["x-unit"] == "N/mm");
    CHECK(s["properties"]["limits"]["properties"]["rapid_feed_mm_min"]["x-unit"] == "mm/min");
    CHECK(s["properties"]["limits"]["properties"]["torque_Nm"]["x-unit"] == "N·m");
    const json& box = s["properties"]["stock"]["properties"]["box_mm"];
    CHECK(box["properties"]["min"]["type"] == "array");
    CHECK(box["properties"]["min"]["minItems"] == 3);
    CHECK(s["required"] == json({"material", "stock"}));

    std::vector<Property> props;
    collect(s, {}, "", props);
    for (const Property& p : props) {
        INFO(p.dotted);
        CHECK_FALSE(p.schema.value("title", "").empty());
    }
}
