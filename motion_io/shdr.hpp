// Public SHDR pieces of motion_io, one line at a time: the time stamp parser, the line tokenizer
// and the key map. The file reader (shdr_reader.cpp) and the live sources (live/) both use them,
// so a line means the same thing whether it comes from a file or from a socket.
#pragma once

#include "motion_io/motion_io.hpp"

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace cutload::motion_io {

// ---- time stamps ----

// An ISO 8601 UTC time stamp as SHDR adapters and MTConnect agents write it,
// e.g. 2022-08-08T13:51:34.7167146Z (a space for the 'T', no 'Z' and an "@duration" suffix are
// accepted; the duration is ignored).
struct IsoTime {
    std::int64_t sec = 0;   // whole seconds since 1970-01-01T00:00:00Z
    double frac = 0;        // the written fraction of the second, 0 <= frac < 1
    // Nanoseconds since the epoch (the fraction rounded to 1 ns: exact for up to 9 digits).
    std::int64_t nanos() const;
};

std::optional<IsoTime> parse_iso_time(std::string_view text);

// `ns` since the epoch as ISO 8601 UTC with 'Z', with as few fraction digits (3 to 9) as represent
// it exactly: format_iso_time(1659966694716714600) == "2022-08-08T13:51:34.7167146Z".
std::string format_iso_time(std::int64_t ns);

// ---- lines ----

enum class ShdrLineKind {
    Blank,      // empty (after dropping a trailing '\r')
    Command,    // "* ..." protocol line (PING, PONG, shdrVersion, ...)
    Short,      // fewer than three '|' fields: not 'timestamp|key|value'
    Data,       // timestamp|key|value|key|value...   (samples and events)
    Condition,  // timestamp|key|LEVEL|native code|qualifier|severity|text, on a line of its own
    Asset,      // timestamp|@COMMAND@|...   (asset commands; may open a multi-line body)
    Multiline,  // timestamp|key|...|--multiline--XXXX: a multi-line value that is not an asset
    Body,       // a line inside a multi-line body, including its closing --multiline--XXXX
};

// Classifies the lines of one SHDR stream in order. Stateful only across multi-line bodies: the
// line that ends in --multiline--XXXX opens one and the line equal to --multiline--XXXX closes it.
// Conditions are recognised only as whole 7-field lines (adapters write them on their own line);
// a data line is split into key/value pairs without a device model, so a message or condition
// in the middle of a data line would be mis-paired.
class ShdrLineTokenizer {
public:
    // `line` without its '\n'. The views in fields() point into `line`.
    ShdrLineKind next(std::string_view line);
    // The '|' fields of the last line (empty for Blank, Command and Body lines).
    const std::vector<std::string_view>& fields() const { return fields_; }
    // A Data line whose last key has no value (the key is then ignored).
    bool odd_fields() const { return fields_.size() >= 3 && (fields_.size() - 1) % 2 != 0; }
    bool in_multiline() const { return !terminator_.empty(); }
    const std::string& multiline_terminator() const { return terminator_; }
    // A new stream (a reconnection): forget a multi-line body that was never closed.
    void reset() { terminator_.clear(); }

private:
    std::vector<std::string_view> fields_;
    std::string terminator_;
};

// Splits on every '|' (SHDR has no escaping).
void split_shdr_fields(std::string_view line, std::vector<std::string_view>& out);

// ---- key map (docs/formats.md, "Key map") ----

// For every channel a list of candidate keys in priority order; the first one the log contains
// wins. Units are those the values are written in.
struct ShdrKeyMap {
    std::vector<std::string> position, x, y, z, feed, spindle, block;
    std::string length_unit = "mm";
    std::string feed_unit = "mm/s";   // MTConnect's unit for PATH_FEEDRATE
    std::string spindle_unit = "rpm";
};

ShdrKeyMap default_shdr_key_map();
// The defaults with the channels a JSON map file names replaced; throws IngestError naming the
// file and key. An empty path gives the defaults.
ShdrKeyMap load_shdr_key_map(const std::string& path);

// Factors from the map's units to canonical ones (mm, mm/min, rpm). --units / --feed-units in
// `opt` override the map; --units alone makes the feed unit <length>/s. Throws
// std::invalid_argument for an unknown unit.
struct ShdrUnitFactors {
    double length_mm = 1, feed_mm_min = 60, spindle_rpm = 1;
};
ShdrUnitFactors shdr_unit_factors(const ShdrKeyMap& map, const ReadOptions& opt = {});

}  // namespace cutload::motion_io
