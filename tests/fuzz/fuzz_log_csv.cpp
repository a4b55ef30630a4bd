// Fuzz target: a CSV motion log, read through every ingest stage (docs/fuzzing.md).
#include "log_check.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    return cutload::fuzz::run_log(data, size, cutload::motion_io::Format::Csv);
}
