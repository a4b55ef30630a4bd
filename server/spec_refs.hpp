// Internal to server: a run spec as the API takes it, with its library references resolved
// (defined in api_runs.cpp; uploads and live runs share it).
#pragma once

#include "common.hpp"

#include <httplib.h>

#include <optional>

namespace cutload::server {

struct Resolved {
    json spec;   // canonical (force_model::to_json) after references are inlined
    std::optional<std::int64_t> machine_id, tool_id, material_id;
};

// Inlines library references (tool_id, tools[k].tool_id, material_id: in the spec or as multipart
// parts of `req`) and fills limits the spec leaves at 0 from the tool's limits, then the machine's
// spindle power and torque. ApiError 400 bad_spec naming the key, 404 for an unknown reference.
Resolved resolve_spec(db::Session& s, json spec, const httplib::Request& req);

}  // namespace cutload::server
