#include "durable_file.hpp"

#include <fmt/format.h>

#include <fcntl.h>
#include <stdexcept>
#include <unistd.h>

namespace cutload::server {

void write_durable(const std::filesystem::path& p, const std::string& data) {
    int fd = ::open(p.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd < 0) throw std::runtime_error(fmt::format("cannot write {}", p.string()));
    std::size_t done = 0;
    while (done < data.size()) {
        ssize_t n = ::write(fd, data.data() + done, data.size() - done);
        if (n <= 0) {
            ::close(fd);
            throw std::runtime_error(fmt::format("cannot write {}", p.string()));
        }
        done += static_cast<std::size_t>(n);
    }
    ::fsync(fd);
    ::close(fd);
}

}  // namespace cutload::server
