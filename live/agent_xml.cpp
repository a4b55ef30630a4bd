// Agent documents with pugixml (live/agent_xml.hpp).
#include "live/agent_xml.hpp"

#include "motion_io/shdr.hpp"

#include <fmt/format.h>
#include <pugixml.hpp>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cstring>

namespace cutload::live {
namespace {

// "m:Header" -> "Header": documents may or may not use a namespace prefix.
std::string_view local_name(const pugi::xml_node& n) {
    const std::string_view name = n.name();
    const auto colon = name.find(':');
    return colon == std::string_view::npos ? name : name.substr(colon + 1);
}

pugi::xml_node child(const pugi::xml_node& parent, std::string_view name) {
    for (pugi::xml_node c = parent.first_child(); c; c = c.next_sibling())
        if (c.type() == pugi::node_element && local_name(c) == name) return c;
    return {};
}

template <class Fn>
void for_each_descendant(const pugi::xml_node& root, std::string_view name, Fn&& fn) {
    for (pugi::xml_node c = root.first_child(); c; c = c.next_sibling()) {
        if (c.type() != pugi::node_element) continue;
        if (local_name(c) == name) fn(c);
        for_each_descendant(c, name, fn);
    }
}

pugi::xml_document load(std::string_view xml, const char* what) {
    pugi::xml_document doc;
    const pugi::xml_parse_result r = doc.load_buffer(xml.data(), xml.size());
    if (!r) throw SourceError(fmt::format("{}: not valid XML at byte {}: {}", what, r.offset, r.description()));
    return doc;
}

std::uint64_t header_number(const pugi::xml_node& header, const char* attr, const char* what, bool required = true) {
    const char* text = header.attribute(attr).value();
    std::uint64_t v = 0;
    const auto [end, ec] = std::from_chars(text, text + std::strlen(text), v);
    if (ec != std::errc() || *end != '\0') {
        if (!required) return 0;
        throw SourceError(fmt::format("{}: Header attribute '{}' is '{}', expected a whole number", what, attr, text));
    }
    return v;
}

std::string_view trim(std::string_view s) {
    while (!s.empty() && std::isspace(static_cast<unsigned char>(s.front()))) s.remove_prefix(1);
    while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.remove_suffix(1);
    return s;
}

// An observation's value: its text, or for a data set / table its entries as SHDR writes them
// ("key=value key=value").
std::string observation_value(const pugi::xml_node& obs) {
    std::string entries;
    bool any = false;
    for (pugi::xml_node c = obs.first_child(); c; c = c.next_sibling()) {
        if (c.type() != pugi::node_element || local_name(c) != "Entry") continue;
        if (any) entries += ' ';
        any = true;
        entries += c.attribute("key").value();
        entries += '=';
        entries += std::string(trim(c.text().get()));
    }
    if (any) return entries;
    return std::string(trim(obs.text().get()));
}

}  // namespace

ProbeDocument parse_probe(std::string_view xml, const std::string& device) {
    const pugi::xml_document doc = load(xml, "probe");
    const pugi::xml_node root = doc.document_element();
    if (local_name(root) == "MTConnectError")
        throw SourceError(fmt::format("probe: the agent answered with an error: {}",
                                      trim(child(child(root, "Errors"), "Error").text().get())));
    if (local_name(root) != "MTConnectDevices")
        throw SourceError(fmt::format("probe: expected an MTConnectDevices document, got <{}>", root.name()));
    ProbeDocument out;
    out.instance_id = header_number(child(root, "Header"), "instanceId", "probe");
    const pugi::xml_node devices = child(root, "Devices");
    std::vector<pugi::xml_node> candidates;
    std::string names;
    for (pugi::xml_node d = devices.first_child(); d; d = d.next_sibling()) {
        if (d.type() != pugi::node_element || local_name(d) != "Device") continue;   // <Agent> is the agent itself
        names += fmt::format("{}{}", names.empty() ? "" : ", ", d.attribute("name").value());
        if (device.empty() || device == d.attribute("name").value() || device == d.attribute("uuid").value())
            candidates.push_back(d);
    }
    if (candidates.empty())
        throw SourceError(device.empty() ? "probe: the agent has no device"
                                         : fmt::format("probe: no device '{}' (the agent has: {})", device, names));
    if (candidates.size() > 1)
        throw SourceError(fmt::format("probe: the agent has several devices ({}); name one in the URL", names));
    const pugi::xml_node d = candidates.front();
    out.device_name = d.attribute("name").value();
    out.device_uuid = d.attribute("uuid").value();
    for_each_descendant(d, "DataItem", [&](const pugi::xml_node& n) {
        DataItemInfo item;
        item.id = n.attribute("id").value();
        item.name = n.attribute("name").value();
        item.category = n.attribute("category").value();
        item.type = n.attribute("type").value();
        item.sub_type = n.attribute("subType").value();
        item.units = n.attribute("units").value();
        item.native_units = n.attribute("nativeUnits").value();
        if (!item.id.empty()) out.items.push_back(std::move(item));
    });
    return out;
}

bool StreamsDocument::has_error(std::string_view code) const {
    return std::any_of(errors.begin(), errors.end(), [&](const AgentError& e) { return e.code == code; });
}

StreamsDocument parse_streams(std::string_view xml, const std::map<std::string, std::string>& keys,
                              const std::string& device_name) {
    const pugi::xml_document doc = load(xml, "streams");
    const pugi::xml_node root = doc.document_element();
    StreamsDocument out;
    if (local_name(root) == "MTConnectError") {
        out.is_error = true;
        // 1.x: <Errors><Error errorCode=..>text</Error></Errors>; 2.6+: <Errors><OutOfRange errorCode=..>
        // <ErrorMessage>text</ErrorMessage>...; 1.0: <Error> directly under the root.
        const auto take = [&](const pugi::xml_node& e) {
            if (!e.attribute("errorCode")) return;
            const pugi::xml_node msg = child(e, "ErrorMessage");
            out.errors.push_back({e.attribute("errorCode").value(), std::string(trim(msg ? msg.text().get() : e.text().get()))});
        };
        for_each_descendant(root, "Errors", [&](const pugi::xml_node& list) {
            for (pugi::xml_node e = list.first_child(); e; e = e.next_sibling())
                if (e.type() == pugi::node_element) take(e);
        });
        if (out.errors.empty()) take(child(root, "Error"));
        out.instance_id = header_number(child(root, "Header"), "instanceId", "error", false);
        return out;
    }
    if (local_name(root) != "MTConnectStreams")
        throw SourceError(fmt::format("streams: expected an MTConnectStreams document, got <{}>", root.name()));
    const pugi::xml_node header = child(root, "Header");
    if (!header) throw SourceError("streams: document without a Header");
    out.instance_id = header_number(header, "instanceId", "streams");
    out.first_sequence = header_number(header, "firstSequence", "streams");
    out.last_sequence = header_number(header, "lastSequence", "streams");
    out.next_sequence = header_number(header, "nextSequence", "streams");
    const pugi::xml_node streams = child(root, "Streams");
    for (pugi::xml_node ds = streams.first_child(); ds; ds = ds.next_sibling()) {
        if (ds.type() != pugi::node_element || local_name(ds) != "DeviceStream") continue;
        if (!device_name.empty() && device_name != ds.attribute("name").value()) continue;
        for (pugi::xml_node cs = ds.first_child(); cs; cs = cs.next_sibling()) {
            if (cs.type() != pugi::node_element || local_name(cs) != "ComponentStream") continue;
            for (pugi::xml_node group = cs.first_child(); group; group = group.next_sibling()) {
                const std::string_view g = local_name(group);
                if (group.type() != pugi::node_element || (g != "Samples" && g != "Events")) continue;
                for (pugi::xml_node obs = group.first_child(); obs; obs = obs.next_sibling()) {
                    if (obs.type() != pugi::node_element) continue;
                    const std::string id = obs.attribute("dataItemId").value();
                    const auto stamp = motion_io::parse_iso_time(obs.attribute("timestamp").value());
                    const std::uint64_t seq = obs.attribute("sequence").as_ullong(0);
                    if (id.empty() || !stamp || seq == 0) {
                        out.warnings.push_back(fmt::format("<{} dataItemId=\"{}\" timestamp=\"{}\" sequence=\"{}\">: "
                                                           "missing or malformed attribute; skipped",
                                                           obs.name(), id, obs.attribute("timestamp").value(),
                                                           obs.attribute("sequence").value()));
                        continue;
                    }
                    Observation o;
                    o.stamp_ns = stamp->nanos();
                    const auto k = keys.find(id);
                    o.key = k != keys.end() ? k->second
                          : obs.attribute("name") ? obs.attribute("name").value() : id;
                    o.value = observation_value(obs);
                    o.sequence = seq;
                    out.observations.push_back(std::move(o));
                }
            }
        }
    }
    std::stable_sort(out.observations.begin(), out.observations.end(),
                     [](const Observation& a, const Observation& b) { return a.sequence < b.sequence; });
    return out;
}

}  // namespace cutload::live
