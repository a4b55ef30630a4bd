// Shared by the tests that run the `cutload` executable as a user would: run it, read what it
// printed and its exit code, find bundled data, get a fresh scratch folder.
#pragma once

#include <catch2/catch.hpp>

#include <array>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <optional>
#include <string>
#include <sys/wait.h>
#include <unistd.h>
#include <vector>

namespace cutload::clitest {

struct Result {
    int exit_code = -1;
    std::string output;   // stdout and stderr together
};

inline Result run(const std::string& args) {
    const std::string cmd = std::string(CUTLOAD_BINARY) + " " + args + " 2>&1";
    Result r;
    FILE* pipe = popen(cmd.c_str(), "r");
    REQUIRE(pipe != nullptr);
    std::array<char, 4096> buf{};
    while (fgets(buf.data(), static_cast<int>(buf.size()), pipe)) r.output += buf.data();
    const int status = pclose(pipe);
    r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    return r;
}

// Sets an environment variable (for the test and the commands it runs) and puts it back after.
struct Env {
    std::string name;
    std::optional<std::string> old;
    Env(std::string n, const std::string& value) : name(std::move(n)) {
        if (const char* v = std::getenv(name.c_str())) old = v;
        ::setenv(name.c_str(), value.c_str(), 1);
    }
    ~Env() {
        if (old)
            ::setenv(name.c_str(), old->c_str(), 1);
        else
            ::unsetenv(name.c_str());
    }
};

inline std::string source(const std::string& rel) { return std::string(CUTLOAD_SOURCE_DIR) + "/" + rel; }

// A fresh, empty scratch folder per test. The process id keeps apart test processes that CTest
// runs side by side (and other checkouts' suites) when they use the same name.
// Removed when the test process ends.
inline std::filesystem::path scratch(const std::string& name) {
    struct Made {
        std::vector<std::filesystem::path> dirs;
        ~Made() {
            std::error_code ec;
            for (const auto& d : dirs) std::filesystem::remove_all(d, ec);
        }
    };
    static Made made;
    const std::filesystem::path dir =
        std::filesystem::temp_directory_path() / ("cutload_cli_test_" + std::to_string(::getpid()) + "_" + name);
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    made.dirs.push_back(dir);
    return dir;
}

}  // namespace cutload::clitest
