#include "staged_file.hpp"

#include <filesystem>
#include <stdexcept>

namespace cutload::force_model {

StagedFile::StagedFile(std::string path) : path_(std::move(path)), tmp_(path_ + ".tmp") {
    out_.open(tmp_, std::ios::trunc | std::ios::binary);
    if (!out_) throw std::runtime_error("cannot write " + tmp_);
}

StagedFile::~StagedFile() {
    if (committed_) return;
    out_.close();
    std::error_code ec;
    std::filesystem::remove(tmp_, ec);
}

void StagedFile::append(std::string_view bytes) {
    out_.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    if (!out_) throw std::runtime_error("writing " + tmp_ + " failed");
    bytes_ += bytes.size();
}

void StagedFile::commit() {
    out_.flush();
    if (!out_) throw std::runtime_error("writing " + tmp_ + " failed");
    out_.close();
    std::error_code ec;
    std::filesystem::rename(tmp_, path_, ec);
    if (ec) throw std::runtime_error("cannot rename " + tmp_ + " to " + path_ + ": " + ec.message());
    committed_ = true;
}

}  // namespace cutload::force_model
