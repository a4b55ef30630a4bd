// Private to force_model: what the run-spec parser reads, for the schema derived from it.
#pragma once

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

namespace cutload::force_model {

struct KeyRead {
    std::string path;   // "tools[].limits.force_N": array indexes written as []
    std::string type;   // number, string, object, array, vec3
    bool required = false;
    std::vector<std::string> options;   // a string's accepted values, when the parser has a list
};

// Parses `spec` (throwing SpecError as parse_run_spec does) and returns every key the parser read
// or looked for, in order, including optional ones the spec leaves out.
std::vector<KeyRead> keys_read(const nlohmann::json& spec);

// The tool shapes the parser accepts ("flat", "ball", ...), in its order.
std::vector<std::string> tool_shape_names();

}  // namespace cutload::force_model
