// RUN.json: parsing and validation. Every error names the key path (e.g. "tool.diameter_mm") and
// says what was expected, because the person reading it is fixing a file by hand.
#include "force_model/force_model.hpp"
#include "cutters/barrel.hpp"
#include "cutters/taper.hpp"
#include "run_spec_reads.hpp"

#include "motion_io/nc_program.hpp"
#include "textio/json.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <functional>
#include <initializer_list>
#include <iomanip>
#include <numbers>
#include <set>
#include <sstream>
#include <string>

namespace cutload::force_model {
namespace {

using nlohmann::json;

// Stock corners and the setup offset are machine-sized: as far from zero as an NC coordinate may be
// (100 m). Beyond that the engine's geometry loses its precision and no part is that large.
const double kMaxAbsCoordinateMm = motion_io::NcLimits{}.max_abs_position_mm;


std::string join(const std::string& path, const std::string& key) {
    return path.empty() ? key : path + "." + key;
}

[[noreturn]] void fail(const std::string& path, const std::string& what) {
    throw SpecError(path + ": " + what);
}

// The published schema (run_spec_schema.cpp) is the parser's own account of what it reads: while
// a recorder is set, every key the readers below consume is noted with its type and whether it was
// required. A key the parser reads is therefore in the schema, and nothing else is.
thread_local std::vector<KeyRead>* t_reads = nullptr;

void note(const std::string& path, const char* type, bool required, std::vector<std::string> options = {}) {
    if (!t_reads) return;
    std::string generic;
    for (std::size_t i = 0; i < path.size(); ++i) {
        generic += path[i];
        if (path[i] == '[') {
            while (i + 1 < path.size() && path[i + 1] != ']') ++i;
        }
    }
    t_reads->push_back({generic, type, required, std::move(options)});
}

// Reads one JSON object, remembering which keys were consumed so that leftovers (typos such as
// "diamter_mm") are reported instead of silently ignored.
class ObjectReader {
public:
    ObjectReader(const json& j, std::string path) : j_(j), path_(std::move(path)) {
        if (!j_.is_object()) fail(path_.empty() ? "spec" : path_, "expected a JSON object");
    }

    bool has(const std::string& key) const { return j_.contains(key) && !j_.at(key).is_null(); }

    // An optional section written as null is accepted as absent.
    void accept_null(const std::string& key) { used_.insert(key); }

    const json& object(const std::string& key) {
        used_.insert(key);
        note(join(path_, key), "object", true);
        if (!j_.contains(key)) fail(join(path_, key), "required key is missing");
        const json& v = j_.at(key);
        if (!v.is_object()) fail(join(path_, key), "expected a JSON object");
        return v;
    }

    double number(const std::string& key) {
        used_.insert(key);
        note(join(path_, key), "number", true);
        if (!j_.contains(key)) fail(join(path_, key), "required key is missing");
        return to_number(key, j_.at(key));
    }

    double number_or(const std::string& key, double fallback) {
        used_.insert(key);
        note(join(path_, key), "number", false);
        return has(key) ? to_number(key, j_.at(key)) : fallback;
    }

    std::string string(const std::string& key, std::vector<std::string> options = {}) {
        used_.insert(key);
        note(join(path_, key), "string", true, std::move(options));
        if (!j_.contains(key)) fail(join(path_, key), "required key is missing");
        const json& v = j_.at(key);
        if (!v.is_string()) fail(join(path_, key), "expected a string");
        return v.get<std::string>();
    }

    // An optional section: null or absent is no section.
    const json* optional_object(const std::string& key) {
        used_.insert(key);
        note(join(path_, key), "object", false);
        if (!has(key)) return nullptr;
        const json& v = j_.at(key);
        if (!v.is_object()) fail(join(path_, key), "expected a JSON object");
        return &v;
    }

    std::optional<double> optional_number(const std::string& key) {
        used_.insert(key);
        note(join(path_, key), "number", false);
        if (!has(key)) return std::nullopt;
        return to_number(key, j_.at(key));
    }

    std::string string_or(const std::string& key, const std::string& fallback) {
        used_.insert(key);
        note(join(path_, key), "string", false);
        if (!has(key)) return fallback;
        const json& v = j_.at(key);
        if (!v.is_string()) fail(join(path_, key), "expected a string");
        return v.get<std::string>();
    }

    void vec3(const std::string& key, double out[3], bool required) {
        used_.insert(key);
        note(join(path_, key), "vec3", required);
        if (!has(key)) {
            if (required) fail(join(path_, key), "required key is missing");
            return;
        }
        const json& v = j_.at(key);
        if (!v.is_array() || v.size() != 3) fail(join(path_, key), "expected an array of 3 numbers [x, y, z]");
        for (int i = 0; i < 3; ++i) {
            if (!v[i].is_number()) fail(join(path_, key) + "[" + std::to_string(i) + "]", "expected a number");
            out[i] = v[i].get<double>();
            if (!std::isfinite(out[i])) fail(join(path_, key) + "[" + std::to_string(i) + "]", "must be finite");
        }
    }

    // Each of a vec3's numbers (already read) within +-limit.
    void vec3_within(const std::string& key, const double v[3], double limit, const char* unit) const {
        for (int i = 0; i < 3; ++i)
            if (!(std::fabs(v[i]) <= limit)) {
                std::ostringstream msg;
                msg << "must be within +-" << limit << " " << unit << ", got " << v[i];
                fail(join(path_, key) + "[" + std::to_string(i) + "]", msg.str());
            }
    }

    std::string key_path(const std::string& key) const { return join(path_, key); }
    const std::string& path() const { return path_; }

    // Call after reading every known key.
    void reject_unknown() const {
        for (const auto& [key, value] : j_.items()) {
            (void)value;
            if (!used_.count(key)) fail(join(path_, key), "unknown key");
        }
    }

private:
    double to_number(const std::string& key, const json& v) const {
        if (!v.is_number()) fail(join(path_, key), "expected a number");
        const double x = v.get<double>();
        if (!std::isfinite(x)) fail(join(path_, key), "must be finite");
        return x;
    }

    const json& j_;
    std::string path_;
    std::set<std::string> used_;
};

void require(bool ok, const std::string& path, const std::string& what) {
    if (!ok) fail(path, what);
}

constexpr std::pair<const char*, ToolShape> kShapes[] = {{"flat", ToolShape::Flat},
                                                         {"ball", ToolShape::Ball},
                                                         {"bull", ToolShape::Bull},
                                                         {"drill", ToolShape::Drill},
                                                         {"chamfer", ToolShape::Chamfer},
                                                         {"barrel", ToolShape::Barrel}};

ToolShape parse_shape(const std::string& s, const std::string& path) {
    for (const auto& [name, shape] : kShapes)
        if (s == name) return shape;
    std::string expected;
    for (const auto& [name, shape] : kShapes) expected += std::string(expected.empty() ? "" : ", ") + "\"" + name + "\"";
    fail(path, "expected one of " + expected + ", got \"" + s + "\"");
}

const char* shape_name(ToolShape s) {
    for (const auto& [name, shape] : kShapes)
        if (s == shape) return name;
    return "flat";
}

bool is_cone(ToolShape s) { return s == ToolShape::Drill || s == ToolShape::Chamfer; }

// T numbers as controls take them (FANUC: up to 8 digits).
constexpr double kMaxToolNumber = 99999999;

// Draft tapers are a few degrees per side; beyond 15 a tool is a cone (a chamfer tool).
constexpr double kMaxTaperDeg = 15;

// Barrel radii of real tools run to about 1500 mm; far beyond, the arc is a cylinder for any depth
// the flutes allow (and for most tools the widest point's height passes the flute length limit
// first).
constexpr double kMaxBarrelRadiusMm = 10000;

// The cutting radius where the flutes end: the tip's unless the flank is tapered.
double top_radius_mm(const ToolSpec& t) {
    if (t.taper_deg == 0) return t.diameter_mm / 2;
    return tapered_flank_radius_mm(t.diameter_mm, t.corner_radius_mm, t.taper_deg, t.flute_length_mm);
}

ToolSpec parse_tool(ObjectReader& r) {
    ToolSpec t;
    t.shape = parse_shape(r.string("shape", tool_shape_names()), r.key_path("shape"));
    t.diameter_mm = r.number("diameter_mm");
    require(t.diameter_mm > 0 && t.diameter_mm <= 200, r.key_path("diameter_mm"), "must be in (0, 200] mm");
    const double R = t.diameter_mm / 2;

    const double flutes = r.number("flutes");
    require(flutes >= 1 && flutes <= 16 && flutes == std::floor(flutes), r.key_path("flutes"),
            "must be a whole number from 1 to 16");
    t.flutes = static_cast<int>(flutes);

    t.helix_deg = r.number("helix_deg");
    require(t.helix_deg >= 0 && t.helix_deg < 70, r.key_path("helix_deg"), "must be in [0, 70) degrees");

    // The corner radius is implied by the shape for flat and ball tools; when given it must agree.
    // A barrel's tip is its own key (tip_radius_mm, a ball on the axis rather than a corner).
    const std::string cr = r.key_path("corner_radius_mm");
    if (t.shape == ToolShape::Barrel) {
        if (r.has("corner_radius_mm")) fail(cr, "not for a barrel tool (its tip ball is tip_radius_mm)");
    } else {
        const double default_corner = t.shape == ToolShape::Bull ? -1.0 : t.shape == ToolShape::Ball ? R : 0.0;
        if (t.shape == ToolShape::Bull && !r.has("corner_radius_mm"))
            fail(r.key_path("corner_radius_mm"), "required for a bull-nose tool");
        t.corner_radius_mm = t.shape == ToolShape::Bull ? r.number("corner_radius_mm")
                                                        : r.number_or("corner_radius_mm", default_corner);
        switch (t.shape) {
            case ToolShape::Flat: require(t.corner_radius_mm == 0, cr, "must be 0 for a flat end mill"); break;
            case ToolShape::Ball:
                require(std::abs(t.corner_radius_mm - R) < 1e-9, cr, "must equal diameter_mm / 2 for a ball end mill");
                break;
            case ToolShape::Bull:
                require(t.corner_radius_mm > 0 && t.corner_radius_mm < R, cr,
                        "must be in (0, diameter_mm / 2) for a bull-nose end mill");
                break;
            case ToolShape::Drill:
            case ToolShape::Chamfer: require(t.corner_radius_mm == 0, cr, "must be 0 for a drill or chamfer tool (a cone)"); break;
            case ToolShape::Barrel: break;   // handled above
        }
    }

    // Cones: the included point angle, and for a chamfer tool the flat at its tip.
    double cone_height_mm = 0;
    if (is_cone(t.shape)) {
        t.point_angle_deg = r.number("point_angle_deg");
        require(t.point_angle_deg >= 20 && t.point_angle_deg <= 170, r.key_path("point_angle_deg"),
                "must be in [20, 170] degrees (118: a twist drill, 90: a spot drill or chamfer mill)");
        if (t.shape == ToolShape::Chamfer) {
            t.tip_diameter_mm = r.number_or("tip_diameter_mm", 0);
            require(t.tip_diameter_mm >= 0 && t.tip_diameter_mm < t.diameter_mm, r.key_path("tip_diameter_mm"),
                    "must be in [0, diameter_mm) mm");
        } else if (r.has("tip_diameter_mm")) {
            fail(r.key_path("tip_diameter_mm"), "only a chamfer tool has a flat tip (a drill's point is sharp)");
        }
        cone_height_mm = (R - t.tip_diameter_mm / 2) / std::tan(t.point_angle_deg / 2 * std::numbers::pi / 180);
    } else {
        for (const char* key : {"point_angle_deg", "tip_diameter_mm"})
            if (r.has(key)) fail(r.key_path(key), "only for a drill or chamfer tool");
    }
    if (t.shape == ToolShape::Barrel) {
        // Document 003's r1 and r2 (diameter_mm is 2 r): the arc's centre lies across the axis, so
        // r1 must pass the widest radius, and the tip ball must fit inside it.
        t.barrel_radius_mm = r.number("barrel_radius_mm");
        require(t.barrel_radius_mm > R && t.barrel_radius_mm <= kMaxBarrelRadiusMm, r.key_path("barrel_radius_mm"),
                "must be greater than diameter_mm / 2 (the flank arc's centre lies across the axis) and at most 10000 mm");
        t.tip_radius_mm = r.number("tip_radius_mm");
        require(t.tip_radius_mm > 0 && t.tip_radius_mm < R, r.key_path("tip_radius_mm"),
                "must be in (0, diameter_mm / 2) mm (the tip ball, centred on the axis, inside the barrel)");
        if (r.has("taper_deg")) fail(r.key_path("taper_deg"), "only for a flat, ball or bull end mill (a barrel's flank is barrel_radius_mm)");
        // The flutes must reach the widest point (below), and they are at most 500 mm long.
        const double widest_mm = barrel_widest_height_mm(t.diameter_mm, t.barrel_radius_mm, t.tip_radius_mm);
        if (widest_mm > 500) {
            std::ostringstream msg;
            msg << std::fixed << std::setprecision(1) << "puts the barrel's widest point " << widest_mm
                << " mm above the tip, beyond the longest flutes (500 mm): a smaller barrel radius";
            fail(r.key_path("barrel_radius_mm"), msg.str());
        }
    } else {
        for (const char* key : {"barrel_radius_mm", "tip_radius_mm"})
            if (r.has(key)) fail(r.key_path(key), "only for a barrel tool");
    }
    if (!is_cone(t.shape) && t.shape != ToolShape::Barrel) {
        // A tapered flank (draft walls, deep ribs): the half angle; diameter_mm stays the tip's.
        t.taper_deg = r.number_or("taper_deg", 0);
        require(t.taper_deg >= 0 && t.taper_deg <= kMaxTaperDeg, r.key_path("taper_deg"),
                "must be in [0, 15] degrees per side (the half angle of the flank; 0: no taper)");
    }
    if (is_cone(t.shape) && r.has("taper_deg"))
        fail(r.key_path("taper_deg"), "only for a flat, ball or bull end mill (a drill's or chamfer tool's cone is "
                                      "point_angle_deg)");

    t.flute_length_mm = r.number("flute_length_mm");
    require(t.flute_length_mm > 0 && t.flute_length_mm <= 500, r.key_path("flute_length_mm"), "must be in (0, 500] mm");
    require(t.flute_length_mm >= t.corner_radius_mm, r.key_path("flute_length_mm"),
            "must be at least corner_radius_mm");
    if (t.taper_deg > 0) {
        // The flank widens up to the end of the flutes: that diameter must still be a tool's.
        const double top_diameter_mm = 2 * top_radius_mm(t);
        if (top_diameter_mm > 200) {
            std::ostringstream msg;
            msg << "with taper_deg " << t.taper_deg << " the flutes end at a diameter of " << top_diameter_mm
                << " mm (limit 200 mm): a shorter flute length or a smaller taper";
            fail(r.key_path("flute_length_mm"), msg.str());
        }
    }
    if (t.shape == ToolShape::Barrel) {
        const double widest_mm = barrel_widest_height_mm(t.diameter_mm, t.barrel_radius_mm, t.tip_radius_mm);
        if (t.flute_length_mm < widest_mm - 1e-9) {
            std::ostringstream msg;
            msg << std::fixed << std::setprecision(3) << "must reach the barrel's widest point, "
                << std::ceil(widest_mm * 1000) / 1000
                << " mm above the tip (where the arc of barrel_radius_mm from the tip ball reaches diameter_mm)";
            fail(r.key_path("flute_length_mm"), msg.str());
        }
    }
    if (t.flute_length_mm < cone_height_mm - 1e-9) {
        std::ostringstream msg;
        msg << "must be at least the cone's height, " << cone_height_mm << " mm (the point widens to diameter_mm there)";
        fail(r.key_path("flute_length_mm"), msg.str());
    }
    t.stickout_mm = r.number("stickout_mm");
    require(t.stickout_mm >= t.flute_length_mm && t.stickout_mm <= 1000, r.key_path("stickout_mm"),
            "must be at least flute_length_mm and at most 1000 mm");

    if (const json* holder = r.optional_object("holder")) {
        ObjectReader h(*holder, r.key_path("holder"));
        t.holder.diameter_mm = h.number("diameter_mm");
        require(t.holder.diameter_mm >= 2 * top_radius_mm(t) - 1e-9 && t.holder.diameter_mm <= 500,
                h.key_path("diameter_mm"),
                t.taper_deg > 0 ? "must be at least the tapered tool's diameter at the end of its flutes and at most 500 mm"
                                : "must be at least the tool diameter and at most 500 mm");
        t.holder.length_mm = h.number("length_mm");
        require(t.holder.length_mm > 0 && t.holder.length_mm <= 1000, h.key_path("length_mm"), "must be in (0, 1000] mm");
        h.reject_unknown();
    }
    return t;
}

ToolSpec parse_single_tool(ObjectReader& r) {
    ToolSpec t = parse_tool(r);
    r.reject_unknown();
    return t;
}

Material parse_material(ObjectReader& r) {
    Material m;
    m.name = r.string_or("name", "");
    m.Ktc_N_mm2 = r.number("Ktc_N_mm2");
    m.Krc_N_mm2 = r.number("Krc_N_mm2");
    m.Kac_N_mm2 = r.number("Kac_N_mm2");
    m.Kte_N_mm = r.number("Kte_N_mm");
    m.Kre_N_mm = r.number("Kre_N_mm");
    m.Kae_N_mm = r.number("Kae_N_mm");
    // Tangential and radial coefficients resist the cut by definition; the axial ones change sign
    // with helix hand and are left free.
    require(m.Ktc_N_mm2 > 0 && m.Ktc_N_mm2 < 2e4, r.key_path("Ktc_N_mm2"), "must be in (0, 20000) N/mm^2");
    require(m.Krc_N_mm2 >= 0 && m.Krc_N_mm2 < 2e4, r.key_path("Krc_N_mm2"), "must be in [0, 20000) N/mm^2");
    require(std::abs(m.Kac_N_mm2) < 2e4, r.key_path("Kac_N_mm2"), "must be in (-20000, 20000) N/mm^2");
    require(m.Kte_N_mm >= 0 && m.Kte_N_mm < 1e3, r.key_path("Kte_N_mm"), "must be in [0, 1000) N/mm");
    require(m.Kre_N_mm >= 0 && m.Kre_N_mm < 1e3, r.key_path("Kre_N_mm"), "must be in [0, 1000) N/mm");
    require(std::abs(m.Kae_N_mm) < 1e3, r.key_path("Kae_N_mm"), "must be in (-1000, 1000) N/mm");
    r.reject_unknown();
    return m;
}

StockBox parse_stock(ObjectReader& r) {
    StockBox b;
    ObjectReader box(r.object("box_mm"), r.key_path("box_mm"));
    box.vec3("min", b.min_mm, true);
    box.vec3("max", b.max_mm, true);
    box.vec3_within("min", b.min_mm, kMaxAbsCoordinateMm, "mm");
    box.vec3_within("max", b.max_mm, kMaxAbsCoordinateMm, "mm");
    static const char* axis[3] = {"x", "y", "z"};
    for (int i = 0; i < 3; ++i)
        require(b.max_mm[i] > b.min_mm[i], box.key_path("max"),
                std::string("must exceed min along ") + axis[i]);
    box.reject_unknown();
    r.reject_unknown();
    return b;
}

Limits parse_limits(ObjectReader& r) {
    Limits l;
    auto read = [&r](const char* key, double& out) {
        out = r.number_or(key, out);
        require(out >= 0, r.key_path(key), "must be >= 0 (0 disables the check)");
    };
    read("force_N", l.force_N);
    read("torque_Nm", l.torque_Nm);
    read("power_kW", l.power_kW);
    read("chip_mm", l.chip_mm);
    read("bending_MPa", l.bending_MPa);
    read("rapid_feed_mm_min", l.rapid_feed_mm_min);
    read("holder_clearance_mm", l.holder_clearance_mm);
    require(l.holder_clearance_mm <= 50, r.key_path("holder_clearance_mm"), "must be <= 50 mm (a clearance shell, not a work envelope)");
    r.reject_unknown();
    return l;
}

LimitOverrides parse_limit_overrides(ObjectReader& r) {
    LimitOverrides l;
    auto read = [&r](const char* key, std::optional<double>& out) {
        out = r.optional_number(key);
        if (out) require(*out >= 0, r.key_path(key), "must be >= 0 (0 disables the check for this tool)");
    };
    read("force_N", l.force_N);
    read("torque_Nm", l.torque_Nm);
    read("power_kW", l.power_kW);
    read("chip_mm", l.chip_mm);
    read("bending_MPa", l.bending_MPa);
    if (r.has("rapid_feed_mm_min"))
        fail(r.key_path("rapid_feed_mm_min"), "the rapid feed is the machine's: set it in the run's limits");
    if (r.has("holder_clearance_mm"))
        fail(r.key_path("holder_clearance_mm"), "the holder clearance is the run's: set it in the run's limits");
    r.reject_unknown();
    return l;
}

// "tools": [{"number": 11, <the fields of "tool">, "limits": {...}}, ...]
std::vector<NumberedTool> parse_tool_table(const json& j) {
    if (!j.is_array()) fail("tools", "expected an array of tools, each {\"number\": T, <the fields of tool>}");
    if (j.empty()) fail("tools", "must list at least one tool (or leave the key out)");
    std::vector<NumberedTool> tools;
    for (std::size_t k = 0; k < j.size(); ++k) {
        ObjectReader r(j[k], "tools[" + std::to_string(k) + "]");
        NumberedTool t;
        const double number = r.number("number");
        require(number >= 0 && number <= kMaxToolNumber && number == std::floor(number), r.key_path("number"),
                "must be a whole T number from 0 to 99999999");
        t.number = static_cast<int>(number);
        for (std::size_t e = 0; e < tools.size(); ++e)
            if (tools[e].number == t.number)
                fail(r.key_path("number"), fmt::format("T{} is already tools[{}]", t.number, e));
        t.tool = parse_tool(r);
        if (const json* limits = r.optional_object("limits")) {
            ObjectReader l(*limits, r.key_path("limits"));
            t.limits = parse_limit_overrides(l);
        }
        r.reject_unknown();
        tools.push_back(std::move(t));
    }
    return tools;
}

Resolution parse_resolution(ObjectReader& r) {
    Resolution res;
    res.angle_step_deg = r.number_or("angle_step_deg", res.angle_step_deg);
    require(res.angle_step_deg >= 0.1 && res.angle_step_deg <= 30, r.key_path("angle_step_deg"),
            "must be in [0.1, 30] degrees");
    res.axial_step_mm = r.number_or("axial_step_mm", res.axial_step_mm);
    require(res.axial_step_mm >= 0.005 && res.axial_step_mm <= 5, r.key_path("axial_step_mm"),
            "must be in [0.005, 5] mm");
    res.grid_mm = r.number_or("grid_mm", res.grid_mm);
    require(res.grid_mm >= 0.005 && res.grid_mm <= 10, r.key_path("grid_mm"), "must be in [0.005, 10] mm");
    r.reject_unknown();
    return res;
}

}  // namespace

std::vector<std::string> tool_shape_names() {
    std::vector<std::string> names;
    for (const auto& [name, shape] : kShapes) names.emplace_back(name);
    return names;
}

RunSpec parse_run_spec(const json& j) {
    ObjectReader root(j, "");
    RunSpec spec;
    // Either may be left out when the other is given; the schema lists both as optional.
    note("tools", "array", false);
    note("tool", "object", false);
    if (root.has("tools")) {
        root.accept_null("tools");
        spec.tools = parse_tool_table(j.at("tools"));
    } else {
        root.accept_null("tools");
    }
    spec.has_tool = root.has("tool") || spec.tools.empty();
    if (spec.has_tool) {
        if (!root.has("tool")) fail("tool", "required key is missing (or give a tool table, \"tools\")");
        ObjectReader r(root.object("tool"), "tool");
        spec.tool = parse_single_tool(r);
    } else {
        root.accept_null("tool");
    }
    {
        ObjectReader r(root.object("material"), "material");
        spec.material = parse_material(r);
    }
    {
        ObjectReader r(root.object("stock"), "stock");
        spec.stock = parse_stock(r);
    }
    if (const json* section = root.optional_object("setup")) {
        ObjectReader r(*section, "setup");
        r.vec3("offset_mm", spec.offset_mm, false);
        r.vec3_within("offset_mm", spec.offset_mm, kMaxAbsCoordinateMm, "mm");
        r.reject_unknown();
    }
    if (const json* section = root.optional_object("limits")) {
        ObjectReader r(*section, "limits");
        spec.limits = parse_limits(r);
    }
    if (const json* section = root.optional_object("resolution")) {
        ObjectReader r(*section, "resolution");
        spec.resolution = parse_resolution(r);
    }
    root.reject_unknown();

    // Only what no machine could build is refused here; what this one can honour is a work limit
    // of the front end (app::WorkLimits::max_stock_cells, --max-stock-cells).
    const double g = spec.resolution.grid_mm;
    if (const double cells = stock_cells(spec.stock, g); cells > kMaxStockRays) {
        std::ostringstream msg;
        msg << "a " << g << " mm grid over the stock box needs " << cells << " cells (at most "
            << kMaxStockRays << " can be built): use a coarser grid or a smaller stock";
        fail("resolution.grid_mm", msg.str());
    }
    return spec;
}

namespace {

// The document's errors and the spec's, both as SpecError starting with the source.
RunSpec parse_document(const std::function<json()>& parse, const std::string& source) {
    json j;
    try {
        j = parse();
    } catch (const textio::TextError& e) {
        throw SpecError(e.what());   // "source:line:column: key: why"
    }
    try {
        return parse_run_spec(j);
    } catch (const SpecError& e) {
        throw SpecError(source + ": " + e.what());
    }
}

}  // namespace

std::vector<KeyRead> keys_read(const json& spec) {
    std::vector<KeyRead> reads;
    struct Reset {
        ~Reset() { t_reads = nullptr; }
    } reset;
    t_reads = &reads;
    parse_run_spec(spec);
    return reads;
}

RunSpec load_run_spec(const std::string& path) {
    return parse_document([&] { return textio::read_json_file(path, "run spec"); }, path);
}

RunSpec parse_run_spec_text(std::string_view text, const std::string& source) {
    return parse_document([&] { return textio::parse_json(text, source); }, source);
}

namespace {

json tool_json(const ToolSpec& t) {
    json tool = {{"shape", shape_name(t.shape)},
                 {"diameter_mm", t.diameter_mm},
                 {"flutes", t.flutes},
                 {"helix_deg", t.helix_deg}};
    if (is_cone(t.shape)) {
        tool["point_angle_deg"] = t.point_angle_deg;
        if (t.shape == ToolShape::Chamfer) tool["tip_diameter_mm"] = t.tip_diameter_mm;
    } else if (t.shape == ToolShape::Barrel) {
        tool["barrel_radius_mm"] = t.barrel_radius_mm;
        tool["tip_radius_mm"] = t.tip_radius_mm;
    } else {
        tool["corner_radius_mm"] = t.corner_radius_mm;
        if (t.taper_deg > 0) tool["taper_deg"] = t.taper_deg;
    }
    tool["flute_length_mm"] = t.flute_length_mm;
    tool["stickout_mm"] = t.stickout_mm;
    if (t.holder.diameter_mm > 0) tool["holder"] = {{"diameter_mm", t.holder.diameter_mm}, {"length_mm", t.holder.length_mm}};
    return tool;
}

json overrides_json(const LimitOverrides& l) {
    json j = json::object();
    auto put = [&j](const char* key, const std::optional<double>& v) {
        if (v) j[key] = *v;
    };
    put("force_N", l.force_N);
    put("torque_Nm", l.torque_Nm);
    put("power_kW", l.power_kW);
    put("chip_mm", l.chip_mm);
    put("bending_MPa", l.bending_MPa);
    return j;
}

}  // namespace

Limits limits_for(const Limits& run, const LimitOverrides& tool) {
    Limits l = run;
    l.force_N = tool.force_N.value_or(run.force_N);
    l.torque_Nm = tool.torque_Nm.value_or(run.torque_Nm);
    l.power_kW = tool.power_kW.value_or(run.power_kW);
    l.chip_mm = tool.chip_mm.value_or(run.chip_mm);
    l.bending_MPa = tool.bending_MPa.value_or(run.bending_MPa);
    return l;
}

const NumberedTool* find_tool(const RunSpec& spec, int number) {
    for (const NumberedTool& t : spec.tools)
        if (t.number == number) return &t;
    return nullptr;
}

int max_flutes(const RunSpec& spec) {
    int n = spec.has_tool ? spec.tool.flutes : 1;
    for (const NumberedTool& t : spec.tools) n = std::max(n, t.tool.flutes);
    return n;
}

json to_json(const RunSpec& s) {
    const auto& m = s.material;
    json j = {
        {"material",
         {{"name", m.name},
          {"Ktc_N_mm2", m.Ktc_N_mm2},
          {"Krc_N_mm2", m.Krc_N_mm2},
          {"Kac_N_mm2", m.Kac_N_mm2},
          {"Kte_N_mm", m.Kte_N_mm},
          {"Kre_N_mm", m.Kre_N_mm},
          {"Kae_N_mm", m.Kae_N_mm}}},
        {"stock",
         {{"box_mm",
           {{"min", {s.stock.min_mm[0], s.stock.min_mm[1], s.stock.min_mm[2]}},
            {"max", {s.stock.max_mm[0], s.stock.max_mm[1], s.stock.max_mm[2]}}}}}},
        {"setup", {{"offset_mm", {s.offset_mm[0], s.offset_mm[1], s.offset_mm[2]}}}},
        {"limits",
         {{"force_N", s.limits.force_N},
          {"torque_Nm", s.limits.torque_Nm},
          {"power_kW", s.limits.power_kW},
          {"chip_mm", s.limits.chip_mm},
          {"bending_MPa", s.limits.bending_MPa},
          {"rapid_feed_mm_min", s.limits.rapid_feed_mm_min}}},
        {"resolution",
         {{"angle_step_deg", s.resolution.angle_step_deg},
          {"axial_step_mm", s.resolution.axial_step_mm},
          {"grid_mm", s.resolution.grid_mm}}},
    };
    if (s.limits.holder_clearance_mm > 0) j["limits"]["holder_clearance_mm"] = s.limits.holder_clearance_mm;
    if (s.has_tool) j["tool"] = tool_json(s.tool);
    if (!s.tools.empty()) {
        json table = json::array();
        for (const NumberedTool& t : s.tools) {
            json e = tool_json(t.tool);
            e["number"] = t.number;
            if (json l = overrides_json(t.limits); !l.empty()) e["limits"] = std::move(l);
            table.push_back(std::move(e));
        }
        j["tools"] = std::move(table);
    }
    return j;
}

}  // namespace cutload::force_model
