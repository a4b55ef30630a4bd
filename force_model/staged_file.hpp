// A result file written under a temporary name beside PATH and renamed to PATH by commit(), so a
// reader never sees it half-written; destroyed without commit() (an error, a cancel) it removes the
// temporary file. The temporary name is new for each writer (created exclusively, never through
// a link planted there), so two runs writing the same PATH do not write into one file.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

namespace cutload::force_model {

class StagedFile {
public:
    explicit StagedFile(std::string path);   // throws std::runtime_error naming PATH
    ~StagedFile();
    StagedFile(const StagedFile&) = delete;
    StagedFile& operator=(const StagedFile&) = delete;

    void append(std::string_view bytes);     // throws std::runtime_error when the write fails
    void commit();
    std::uint64_t bytes() const { return bytes_; }
    const std::string& temporary_path() const { return tmp_; }

private:
    std::string path_, tmp_;
    int fd_ = -1;
    std::uint64_t bytes_ = 0;
    std::uint64_t written_back_ = 0;   // bytes whose writeback append() has started
    bool committed_ = false;
};

}  // namespace cutload::force_model
