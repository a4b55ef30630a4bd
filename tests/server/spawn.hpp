// Shared by the server tests that run the real binary: spawning `cutload serve` on a free port
// with its output in a log file, and waiting for a process to end.
#pragma once

#include "harness.hpp"

#include <algorithm>
#include <fcntl.h>
#include <regex>
#include <csignal>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

namespace cutload::test {

inline std::string read_text(const fs::path& p) {
    std::ifstream in(p);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

// Runs the cutload binary with its output in `log`; returns the pid.
inline pid_t spawn(const std::vector<std::string>& args, const fs::path& log) {
    pid_t pid = ::fork();
    REQUIRE(pid >= 0);
    if (pid == 0) {
        // Gone with the test: a test that fails (or is timed out) leaves no server or worker behind.
        ::prctl(PR_SET_PDEATHSIG, SIGKILL);
        int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
        ::dup2(fd, 1);
        ::dup2(fd, 2);
        std::vector<char*> argv;
        for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
        argv.push_back(nullptr);
        ::execv(argv[0], argv.data());
        ::_exit(127);
    }
    return pid;
}

struct Proc {
    pid_t pid = -1;
    int port = 0;
};

inline Proc start_server(const fs::path& db, const fs::path& log, const std::vector<std::string>& extra = {}) {
    const std::size_t before = read_text(log).size();
    Proc p;
    std::vector<std::string> args{CUTLOAD_BINARY, "serve", "--listen", "127.0.0.1:0", "--db", db.string(), "--workers", "1",
                                  "--device", "cpu"};
    // --drain-s 0 unless the caller gives its own.
    if (std::find(extra.begin(), extra.end(), "--drain-s") == extra.end()) args.insert(args.end(), {"--drain-s", "0"});
    // A PostgreSQL URL names no folder for uploads: beside the log, in the test's directory. Its
    // jobs left running by a killed server are re-queued when their lease ends: a short one.
    if (on_postgres()) args.insert(args.end(), {"--data-dir", (log.parent_path() / "data").string()});
    if (on_postgres() && std::find(extra.begin(), extra.end(), "--lease-s") == extra.end())
        args.insert(args.end(), {"--lease-s", "1"});
    args.insert(args.end(), extra.begin(), extra.end());
    p.pid = spawn(args, log);
    static const std::regex listening(R"(listening on http://127\.0\.0\.1:(\d+))");
    for (int i = 0; i < 500 && p.port == 0; ++i) {
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
        const std::string out = read_text(log).substr(before);
        std::smatch m;
        if (std::regex_search(out, m, listening)) p.port = std::stoi(m[1]);
    }
    INFO(read_text(log));
    REQUIRE(p.port > 0);
    return p;
}

inline int wait_exit(pid_t pid) {
    int status = 0;
    ::waitpid(pid, &status, 0);
    return status;
}

}  // namespace cutload::test
