// Files the service promises to keep: written and flushed to the disk before the answer that
// says they are stored ("stored before 202").
#pragma once

#include <filesystem>
#include <string>

namespace cutload::server {

// Writes data to p (replacing it) and fsyncs it; throws std::runtime_error naming p on failure.
void write_durable(const std::filesystem::path& p, const std::string& data);

}  // namespace cutload::server
