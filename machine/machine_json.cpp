// Machine definitions from JSON (docs/machines.md). Every error names the key path, because the
// person reading it is fixing a file by hand.
#include "json_reader.hpp"

#include <fmt/format.h>

#include <cctype>
#include <cmath>
#include <fstream>
#include <sstream>

namespace cutload::machine {

using detail::fail;
using detail::ObjectReader;
using nlohmann::json;

namespace {

bool is_linear_letter(char c) { return c == 'X' || c == 'Y' || c == 'Z'; }
bool is_rotary_letter(char c) { return c == 'A' || c == 'B' || c == 'C'; }

// The settings an axis has in both forms: pivot, sense, limits, channel.
void read_axis_settings(ObjectReader& r, Axis& a) {
    if (a.rotary()) {
        a.pivot_mm = detail::vec3_at(r.at("pivot_mm"), r.key_path("pivot_mm"));
    } else if (r.find("pivot_mm")) {
        fail(r.key_path("pivot_mm"), fmt::format("linear axis {} has no pivot", a.name));
    }
    if (const json* s = r.find("sense")) {
        const double v = detail::number_at(*s, r.key_path("sense"));
        if (v != 1 && v != -1) fail(r.key_path("sense"), "must be 1 or -1");
        a.sense = static_cast<int>(v);
    }
    const std::string good = a.rotary() ? "limits_deg" : "limits_mm";
    const std::string bad = a.rotary() ? "limits_mm" : "limits_deg";
    if (r.find(bad))
        fail(r.key_path(bad), fmt::format("{} axis {} takes {}", a.rotary() ? "rotary" : "linear", a.name, good));
    if (const json* l = r.find(good)) {
        const std::string kp = r.key_path(good);
        if (!l->is_array() || l->size() != 2) fail(kp, "expected [lower, upper]");
        a.lower = detail::number_at((*l)[0], kp + "[0]");
        a.upper = detail::number_at((*l)[1], kp + "[1]");
        if (!(a.lower < a.upper)) fail(kp, "lower must be below upper");
    }
    a.channel = std::string(1, static_cast<char>(std::tolower(static_cast<unsigned char>(a.name))));
    if (r.find("channel")) {
        a.channel = r.string("channel");
        if (a.channel.empty()) fail(r.key_path("channel"), "must not be empty");
    }
}

Axis parse_explicit_axis(const json& j, Side side, const std::string& path) {
    ObjectReader r(j, path);
    Axis a;
    a.side = side;
    const std::string name = r.string("name");
    if (name.size() != 1 || !(is_linear_letter(name[0]) || is_rotary_letter(name[0])))
        fail(r.key_path("name"), fmt::format("expected one of X, Y, Z, A, B, C, got \"{}\"", name));
    a.name = name[0];
    const std::string type = r.string("type");
    if (type == "linear") a.type = AxisType::Linear;
    else if (type == "rotary") a.type = AxisType::Rotary;
    else fail(r.key_path("type"), fmt::format("expected \"linear\" or \"rotary\", got \"{}\"", type));
    if (is_linear_letter(a.name) == a.rotary())
        fail(r.key_path("type"), fmt::format("axis {} is {} (X, Y, Z move; A, B, C turn)", a.name,
                                             is_linear_letter(a.name) ? "linear" : "rotary"));
    a.direction = detail::unit_at(r.at("direction"), r.key_path("direction"));
    read_axis_settings(r, a);
    r.reject_unknown();
    return a;
}

std::vector<Axis> parse_explicit_chain(ObjectReader& r) {
    std::vector<Axis> chain;
    for (const auto& [key, side] : {std::pair{std::string("workpiece_side"), Side::Workpiece},
                                    std::pair{std::string("tool_side"), Side::Tool}}) {
        const json& list = r.at(key);
        if (!list.is_array())
            fail(r.key_path(key), "expected an array of axes (an empty array when no axis moves this side)");
        for (std::size_t i = 0; i < list.size(); ++i)
            chain.push_back(parse_explicit_axis(list[i], side, detail::index_key(r.key_path(key), i)));
    }
    return chain;
}

std::vector<Axis> parse_code_chain(ObjectReader& r) {
    std::vector<Axis> chain = parse_form_shaping_code(r.string("code"), r.key_path("code"));
    const json* axes = r.find("axes");
    static const json kEmpty = json::object();
    ObjectReader ar(axes ? *axes : kEmpty, r.key_path("axes"));
    for (Axis& a : chain) {
        const std::string letter(1, a.name);
        if (!ar.has(letter)) {
            ar.mark_used(letter);
            if (a.rotary()) fail(ar.key_path(letter), fmt::format("rotary axis {} needs its pivot_mm", a.name));
            continue;
        }
        ObjectReader axr(ar.at(letter), ar.key_path(letter));
        read_axis_settings(axr, a);
        for (const char* fixed : {"name", "type", "direction"})
            if (axr.has(fixed))
                fail(axr.key_path(fixed), "is set by the code; use the explicit form (workpiece_side, tool_side) "
                                          "for axes off the machine's X, Y, Z directions");
        axr.reject_unknown();
    }
    for (const auto& [key, value] : ar.object().items()) {
        (void)value;
        bool known = false;
        for (const Axis& a : chain) known = known || key == std::string(1, a.name);
        if (!known) fail(ar.key_path(key), "is not an axis of the code");
    }
    return chain;
}

Spindle parse_spindle(ObjectReader& r) {
    Spindle s;
    if (const json* g = r.find("gauge_point_mm")) s.gauge_point_mm = detail::vec3_at(*g, r.key_path("gauge_point_mm"));
    if (const json* a = r.find("axis")) s.axis = detail::unit_at(*a, r.key_path("axis"));
    if (const json* x = r.find("x_direction")) s.x_direction = detail::unit_at(*x, r.key_path("x_direction"));
    // Only the part normal to the axis counts; nearly parallel leaves no direction to keep.
    const Eigen::Vector3d xn = s.x_direction - s.x_direction.dot(s.axis) * s.axis;
    if (xn.norm() < 1e-3) fail(r.key_path("x_direction"), "must not be parallel to the spindle axis");
    s.x_direction = xn.normalized();
    r.reject_unknown();
    return s;
}

void validate_chain(const std::vector<Axis>& chain, const std::string& where) {
    std::vector<const Axis*> linear, rotary;
    for (std::size_t i = 0; i < chain.size(); ++i) {
        for (std::size_t k = 0; k < i; ++k)
            if (chain[k].name == chain[i].name) fail(where, fmt::format("axis {} appears twice", chain[i].name));
        (chain[i].rotary() ? rotary : linear).push_back(&chain[i]);
    }
    if (linear.size() != 3)
        fail(where, fmt::format("needs exactly three linear axes (X, Y, Z), has {}", linear.size()));
    Eigen::Matrix3d D;
    for (int i = 0; i < 3; ++i) D.col(i) = linear[static_cast<std::size_t>(i)]->direction;
    if (std::abs(D.determinant()) < 1e-3)
        fail(where, "the directions of the linear axes must span space (they lie in one plane)");
    if (rotary.size() > 2) fail(where, fmt::format("at most two rotary axes are supported, has {}", rotary.size()));
    if (rotary.size() == 2 && rotary[0]->direction.cross(rotary[1]->direction).norm() < 1e-3)
        fail(where, fmt::format("rotary axes {} and {} are parallel", rotary[0]->name, rotary[1]->name));
}

}  // namespace

const char* kind_name(MachineKind kind) {
    switch (kind) {
        case MachineKind::ThreeAxis: return "three-axis";
        case MachineKind::FourAxisTable: return "four-axis table";
        case MachineKind::FourAxisHead: return "four-axis head";
        case MachineKind::TableTable: return "table-table";
        case MachineKind::HeadTable: return "head-table";
        case MachineKind::HeadHead: return "head-head";
    }
    return "?";
}

MachineKind Machine::kind() const {
    int table = 0, head = 0;
    for (const Axis& a : chain)
        if (a.rotary()) (a.side == Side::Workpiece ? table : head) += 1;
    if (table + head == 0) return MachineKind::ThreeAxis;
    if (table + head == 1) return table ? MachineKind::FourAxisTable : MachineKind::FourAxisHead;
    if (table == 2) return MachineKind::TableTable;
    if (head == 2) return MachineKind::HeadHead;
    return MachineKind::HeadTable;
}

bool Machine::has_errors() const {
    for (const Axis& a : chain)
        if (a.errors.any()) return true;
    return false;
}

std::size_t Machine::index_of(char axis_name) const {
    for (std::size_t i = 0; i < chain.size(); ++i)
        if (chain[i].name == axis_name) return i;
    throw MachineError(name.empty() ? fmt::format("the machine has no axis {}", axis_name)
                                    : fmt::format("machine \"{}\" has no axis {}", name, axis_name));
}

void set_errors(Machine& machine, const json& errors, const std::string& path) {
    ObjectReader r(errors, path);
    std::vector<AxisErrors> parsed;   // assigned only when every axis parsed: nothing half-applied
    for (const Axis& a : machine.chain) {
        const std::string letter(1, a.name);
        if (const json* e = r.find(letter)) {
            parsed.push_back(detail::parse_axis_errors(*e, a, r.key_path(letter)));
        } else {
            parsed.emplace_back();
            parsed.back().reference_point_mm = a.rotary() ? a.pivot_mm : Eigen::Vector3d::Zero();
        }
    }
    for (const auto& [key, value] : errors.items()) {
        (void)value;
        bool known = false;
        for (const Axis& a : machine.chain) known = known || key == std::string(1, a.name);
        if (!known) fail(r.key_path(key), "is not an axis of this machine");
    }
    for (std::size_t i = 0; i < machine.chain.size(); ++i) machine.chain[i].errors = parsed[i];
}

Machine parse_machine(const json& j) {
    ObjectReader r(j, "");
    Machine m;
    if (r.find("name")) m.name = r.string("name");
    const bool explicit_form = r.has("workpiece_side") || r.has("tool_side");
    if (explicit_form && r.has("code"))
        fail("code", "give the chain either as a code or as workpiece_side and tool_side, not both");
    if (explicit_form) {
        m.chain = parse_explicit_chain(r);
        if (r.has("axes")) fail("axes", "belongs to the code form; in the explicit form each axis carries its settings");
    } else if (r.has("code")) {
        m.chain = parse_code_chain(r);
    } else {
        fail("", "a machine needs its chain: \"workpiece_side\" and \"tool_side\" (explicit form) or \"code\"");
    }
    validate_chain(m.chain, explicit_form ? "workpiece_side, tool_side" : "code");
    static const json kEmpty = json::object();
    const json* sp = r.find("spindle");
    ObjectReader sr(sp ? *sp : kEmpty, "spindle");
    m.spindle = parse_spindle(sr);
    set_errors(m, r.find("errors") ? r.at("errors") : json::object(), "errors");
    r.reject_unknown();
    return m;
}

namespace {

// `name` stands for the file in messages.
json read_json_file(const std::string& path, const std::string& name) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw MachineError(name + ": cannot open the file");
    std::ostringstream ss;
    ss << in.rdbuf();
    try {
        return json::parse(ss.str());
    } catch (const json::parse_error& e) {
        throw MachineError(fmt::format("{}: not valid JSON (byte {}): {}", name, e.byte, e.what()));
    }
}

}  // namespace

Machine load_machine(const std::string& path, const std::string& shown_as) {
    const std::string& name = shown_as.empty() ? path : shown_as;
    const json j = read_json_file(path, name);
    try {
        return parse_machine(j);
    } catch (const MachineError& e) {
        throw MachineError(name + ": " + e.what());
    }
}

void load_errors(Machine& machine, const std::string& path, const std::string& shown_as) {
    const std::string& name = shown_as.empty() ? path : shown_as;
    const json j = read_json_file(path, name);
    try {
        set_errors(machine, j, "");
    } catch (const MachineError& e) {
        throw MachineError(name + ": " + e.what());
    }
}

}  // namespace cutload::machine
