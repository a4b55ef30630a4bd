// Public, reading-by-reading access to a log as the readers see it: canonical units (s, mm,
// mm/min, rpm), file order, before any sampling repair. Used by the replay adapter (live/) to
// re-send a CSV log as an SHDR stream.
#pragma once

#include "motion_io/motion_io.hpp"

#include <cstddef>
#include <functional>
#include <string>
#include <string_view>

namespace cutload::motion_io {

struct LogReading {
    enum class Channel { Position, Feed, Spindle, Block };
    Channel channel = Channel::Position;
    double t_s = 0;                   // the reading's own time stamp (per-channel stamps kept)
    double value[3] = {0, 0, 0};      // Position: x y z mm; Feed: mm/min; Spindle: rpm (signed)
    std::string_view block;           // Block: the block name (valid during the callback)
    std::size_t line = 0;             // line in the file
};

// Every reading of a CSV log, validated as `ingest` validates it (IngestError names file:line).
// A row's readings come in time order, rows in file order. Streams: bounded memory.
void read_csv_readings(const std::string& path, const ReadOptions& opt,
                       const std::function<void(const LogReading&)>& on_reading);

// Csv or Shdr, as --format auto decides (docs/formats.md).
Format detect_log_format(const std::string& path);

}  // namespace cutload::motion_io
