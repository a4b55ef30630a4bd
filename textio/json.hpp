// JSON that people write by hand: run specs, tools, channel maps. Every reader of such a file
// parses it here, so a problem is told the same way everywhere: the file, the line and column,
// and the key path being read ("tool.diameter_mm", "stock.box_mm.min[0]"), in one line.
//
//   - the text is decoded first (text.hpp): UTF-8, else Windows-1252/Latin-1, so a material
//     named in an old editor's code page reads; NUL and undefined bytes are refused with their place;
//   - a number beyond the range of a double (1e400) is refused naming its key, where the JSON
//     library alone would only say "number overflow parsing '1e400'";
//   - nesting deeper than kMaxJsonDepth levels is refused (no hand-written file needs it, and every
//     later walk over the document is then bounded);
//   - a file over kMaxJsonFileBytes is refused before it is read.
#pragma once

#include "textio/text.hpp"

#include <nlohmann/json_fwd.hpp>

#include <cstddef>
#include <string>
#include <string_view>

namespace cutload::textio {

inline constexpr std::size_t kMaxJsonDepth = 64;
inline constexpr std::size_t kMaxJsonFileBytes = std::size_t{16} << 20;   // 16 MiB

// A JSON text that cannot be read. what() is "source:line:column: key: why" (parts that do not
// apply left out); key() is the key path where the problem lies, empty at the top level.
class JsonError : public TextError {
public:
    JsonError(std::string source, std::size_t line, std::size_t column, std::string key, const std::string& why);
    const std::string& key() const { return key_; }

private:
    std::string key_;
};

// The document in `text`; `source` names it in errors (a path, "part spec"). Throws JsonError.
nlohmann::json parse_json(std::string_view text, std::string_view source);

// The document in the file at `path`; `what` names the file in the error for a file that cannot
// be opened ("path: cannot open the run spec"). Throws JsonError.
nlohmann::json read_json_file(const std::string& path, std::string_view what);

}  // namespace cutload::textio
