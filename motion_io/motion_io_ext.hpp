// Additions to the motion_io contract (motion_io.hpp stays as the lead wrote it).
#pragma once

#include "motion_io/motion_io.hpp"

#include <nlohmann/json.hpp>

namespace cutload::motion_io {

// The report as one JSON object: file, format, duration_s, sessions, blocks,
// channels.<name>.{samples, interval_s.{min,median,max}, update_period_s, stale_dropped},
// feed_mm_min.{raw,repaired}.{min,max}, warnings[{code, count, message}].
nlohmann::json report_to_json(const IngestReport& report);

}  // namespace cutload::motion_io
