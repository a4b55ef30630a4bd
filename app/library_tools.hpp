// A run's tool table may name library tools by id instead of writing them out:
//   "tools": [{"number": 11, "tool_id": 3}, {"number": 12, "tool_id": 5, "limits": {"force_N": 400}}]
// Each such entry becomes the library tool's fields with the table's number, and its limits: the
// library tool's non-zero limits (as for a run's single `tool_id`), any the entry gives winning.
// The run spec parser (force_model) knows no library; front ends resolve here first, with the
// lookup their storage gives.
#pragma once

#include "app/inputs.hpp"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace cutload::app {

// A stored library tool's body as the libraries keep it: {"tool": {...}, "limits": {...}};
// nullopt when there is no tool with that id.
using LibraryToolLookup = std::function<std::optional<nlohmann::json>(std::int64_t id)>;

// A tool_id that names no library tool: key() is "tools[k].tool_id".
class UnknownLibraryTool : public InputError {
public:
    UnknownLibraryTool(std::string key, std::int64_t id);
    std::int64_t id() const { return id_; }

private:
    std::int64_t id_;
};

struct LibraryToolRef {
    int number = 0;          // T number in the table
    std::int64_t tool_id = 0;
};

// The spec with every tools[k].tool_id replaced by the library tool; the references it resolved,
// in table order. InputError naming tools[k].tool_id for an id that is not an integer or comes
// with tool fields of its own; UnknownLibraryTool for an id the lookup does not know. A spec
// without a table, or whose table names no library tool, comes back unchanged.
nlohmann::json resolve_library_tools(nlohmann::json spec, const LibraryToolLookup& lookup,
                                     std::vector<LibraryToolRef>* refs = nullptr);

}  // namespace cutload::app
