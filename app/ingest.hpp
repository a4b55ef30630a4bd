// Use cases on a log alone: inspect it (sampling, sessions, warnings), ingest it into the uniform
// motion model the engine takes, resample it to CSV.
#pragma once

#include "app/control.hpp"
#include "app/inputs.hpp"
#include "motion_io/motion_io.hpp"

#include <cstddef>
#include <string>

namespace cutload::app {

// Streams the log with bounded memory: channels, sampling, CNC grid, first position, warnings.
// motion_io::IngestError naming file and line for a bad log.
motion_io::IngestReport inspect_log(const std::string& path, const motion_io::ReadOptions& options);

struct IngestedLog {
    motion_io::MotionModel motion;
    motion_io::IngestReport report;
};

// The whole log in memory, repaired and resampled on options.step_ms (phase Ingest). The reader
// itself runs to its end: a cancel is honoured as soon as it returns.
IngestedLog ingest_log(const std::string& path, const motion_io::ReadOptions& options, const Control& control = {});

struct Resampled {
    std::size_t rows = 0;
    motion_io::IngestReport report;
};

// The repaired log on its uniform step as CSV (t_s,x_mm,...,block), streamed with bounded memory;
// `out_csv` is written only when the whole log was read.
Resampled resample_log(const std::string& path, const motion_io::ReadOptions& options, const std::string& out_csv);

}  // namespace cutload::app
