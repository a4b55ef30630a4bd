// Shared by the fuzz targets (docs/fuzzing.md): the input as a file for the readers that take a
// path, and the checks every target makes besides the sanitizers'.
//
// A target catches only the error type its parser documents for bad input; any other exception
// escapes, and libFuzzer reports it as a crash: the front ends would show it as a bare message
// (CLI exit 1) or a 500.
#pragma once

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>
#include <sys/mman.h>
#include <unistd.h>

namespace cutload::fuzz {

// The input bytes as a file the readers open by path. A memory file (memfd) reached through
// /proc/self/fd: nothing touches the disk, and every open reads from the start.
class InputFile {
public:
    InputFile() {
        fd_ = ::memfd_create("cutload_fuzz_input", MFD_CLOEXEC);
        if (fd_ < 0) {
            std::perror("memfd_create");
            std::abort();
        }
        path_ = "/proc/self/fd/" + std::to_string(fd_);
    }
    const std::string& write(const std::uint8_t* data, std::size_t size) {
        if (::ftruncate(fd_, 0) != 0) std::abort();
        std::size_t done = 0;
        while (done < size) {
            const ssize_t n = ::pwrite(fd_, data + done, size - done, static_cast<off_t>(done));
            if (n <= 0) std::abort();
            done += static_cast<std::size_t>(n);
        }
        return path_;
    }

private:
    int fd_ = -1;
    std::string path_;
};

// A broken invariant: print it and abort, which libFuzzer records as a crash with its input.
[[noreturn]] inline void broken(const std::string& what) {
    std::fprintf(stderr, "cutload fuzz: invariant broken: %s\n", what.c_str());
    std::abort();
}

// No NaN or infinity in a document cutload writes (nlohmann would write them as null).
inline void check_finite(const nlohmann::json& j, const std::string& where = "") {
    if (j.is_number_float() && !std::isfinite(j.get<double>())) broken("non-finite number at '" + where + "'");
    if (j.is_object())
        for (const auto& [k, v] : j.items()) check_finite(v, where + "." + k);
    if (j.is_array())
        for (std::size_t i = 0; i < j.size(); ++i) check_finite(j[i], where + "[" + std::to_string(i) + "]");
}

// The document as the service would send it: must serialize (valid UTF-8) and hold finite numbers.
inline void check_output(const nlohmann::json& j) {
    check_finite(j);
    (void)j.dump();   // throws type_error 316 on invalid UTF-8: escapes as a crash
}

inline std::string_view as_text(const std::uint8_t* data, std::size_t size) {
    return {reinterpret_cast<const char*>(data), size};
}

}  // namespace cutload::fuzz
