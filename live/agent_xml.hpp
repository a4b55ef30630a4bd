// MTConnect agent documents (MTConnectDevices, MTConnectStreams, MTConnectError) read with
// pugixml into what the agent source needs. Element names are matched without their namespace
// prefix, so documents of every schema version (1.x to 2.x) read alike.
#pragma once

#include "live/live.hpp"

#include <cstdint>
#include <map>
#include <string>
#include <string_view>
#include <vector>

namespace cutload::live {

struct DataItemInfo {
    std::string id, name;           // SHDR adapters send either; observations are keyed by key()
    std::string category;           // SAMPLE, EVENT, CONDITION
    std::string type, sub_type;     // e.g. PATH_POSITION, PATH_FEEDRATE / ACTUAL
    std::string units, native_units;   // e.g. MILLIMETER/SECOND (what the agent reports), MILLIMETER/MINUTE
    const std::string& key() const { return name.empty() ? id : name; }
};

struct ProbeDocument {
    std::uint64_t instance_id = 0;
    std::string device_name, device_uuid;
    std::vector<DataItemInfo> items;   // document order
};

// The device named (or with the uuid) `device`; with `device` empty the document's only Device
// (the agent's own <Agent> device does not count). Throws SourceError saying what is missing.
ProbeDocument parse_probe(std::string_view xml, const std::string& device);

struct AgentError {
    std::string code;      // e.g. OUT_OF_RANGE, NO_DEVICE, INVALID_REQUEST
    std::string message;
};

// An MTConnectStreams document (current or sample) or an MTConnectError document.
struct StreamsDocument {
    bool is_error = false;
    std::vector<AgentError> errors;   // is_error only
    std::uint64_t instance_id = 0;
    std::uint64_t first_sequence = 0, last_sequence = 0, next_sequence = 0;
    // Samples and events of the device, sorted by sequence (the document groups them by
    // component). Conditions are left out; a data set's entries become "key=value key=value".
    // Keyed by the probe's name for their dataItemId.
    std::vector<Observation> observations;
    std::vector<std::string> warnings;   // observations skipped (no time stamp, no sequence)
    bool has_error(std::string_view code) const;
};

// `keys`: dataItemId -> observation key (from the probe). `device_name` selects the DeviceStream.
// Throws SourceError for a document that is neither, or has no Header.
StreamsDocument parse_streams(std::string_view xml, const std::map<std::string, std::string>& keys,
                              const std::string& device_name);

}  // namespace cutload::live
