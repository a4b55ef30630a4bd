#include "staged_file.hpp"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fcntl.h>
#include <random>
#include <stdexcept>
#include <unistd.h>

namespace cutload::force_model {

namespace {

std::string why() { return std::strerror(errno); }

}  // namespace

StagedFile::StagedFile(std::string path) : path_(std::move(path)) {
    // O_EXCL: a name that exists (a file, or a link someone planted) is never opened; another
    // suffix is tried instead. Mode 0666 less the umask, as the file's final name would get.
    std::random_device seed;
    std::mt19937_64 rng(seed() ^ (std::uint64_t(::getpid()) << 32));
    for (int attempt = 0; attempt < 16 && fd_ < 0; ++attempt) {
        char suffix[32];
        std::snprintf(suffix, sizeof suffix, ".tmp-%08llx", static_cast<unsigned long long>(rng() & 0xffffffffull));
        tmp_ = path_ + suffix;
        fd_ = ::open(tmp_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
        if (fd_ < 0 && errno != EEXIST) break;
    }
    if (fd_ < 0) throw std::runtime_error("cannot write " + path_ + " (temporary " + tmp_ + "): " + why());
}

StagedFile::~StagedFile() {
    if (fd_ >= 0) ::close(fd_);
    if (!committed_) ::unlink(tmp_.c_str());
}

void StagedFile::append(std::string_view bytes) {
    std::size_t done = 0;
    while (done < bytes.size()) {
        const ssize_t n = ::write(fd_, bytes.data() + done, bytes.size() - done);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) throw std::runtime_error("writing " + tmp_ + " failed: " + why());
        done += static_cast<std::size_t>(n);
    }
    bytes_ += bytes.size();
    // Writeback started as the file grows, on the writer's thread: ext4 otherwise writes the whole
    // delayed-allocation file inside commit()'s rename when it replaces an existing file (its
    // auto_da_alloc), which held `cutload predict` 23-32 ms at exit for a 26.5 MB FORCES.csv. Whole
    // pages only: the last, partial one would be written again. Only a hint: errors are ignored.
    constexpr std::uint64_t kWritebackBytes = 1 << 20, kPageBytes = 4096;
    const std::uint64_t whole_pages_end = bytes_ / kPageBytes * kPageBytes;
    if (whole_pages_end - written_back_ >= kWritebackBytes) {
        ::sync_file_range(fd_, off64_t(written_back_), off64_t(whole_pages_end - written_back_), SYNC_FILE_RANGE_WRITE);
        written_back_ = whole_pages_end;
    }
}

void StagedFile::commit() {
    const int fd = fd_;
    fd_ = -1;
    if (::close(fd) != 0) throw std::runtime_error("writing " + tmp_ + " failed: " + why());
    if (std::rename(tmp_.c_str(), path_.c_str()) != 0)
        throw std::runtime_error("cannot rename " + tmp_ + " to " + path_ + ": " + why());
    committed_ = true;
}

}  // namespace cutload::force_model
