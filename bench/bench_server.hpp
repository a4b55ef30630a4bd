// The benchmarks that measure the service run the built `cutload serve` as a child process and
// read its memory from /proc.
#pragma once

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace cutload::bench {

// A field of /proc/PID/status in KiB: "VmRSS:" (resident now) or "VmHWM:" (peak resident).
inline long rss_kib(pid_t pid, const char* field = "VmRSS:") {
    std::ifstream in("/proc/" + std::to_string(pid) + "/status");
    std::string line;
    const std::size_t n = std::strlen(field);
    while (std::getline(in, line))
        if (line.compare(0, n, field) == 0) return std::strtol(line.c_str() + n, nullptr, 10);
    return 0;
}

// `cutload serve` as a child process; its first stdout line names the port. Stopped with SIGTERM.
struct ServerProcess {
    pid_t pid = -1;
    int port = 0;

    ServerProcess(const std::string& cutload, const std::vector<std::string>& args) {
        int out[2];
        if (::pipe(out) != 0) throw std::runtime_error("pipe failed");
        pid = ::fork();
        if (pid == 0) {
            ::dup2(out[1], STDOUT_FILENO);
            ::close(out[0]);
            ::close(out[1]);
            std::vector<char*> argv{const_cast<char*>(cutload.c_str())};
            for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
            argv.push_back(nullptr);
            ::execv(cutload.c_str(), argv.data());
            std::perror("exec cutload");
            ::_exit(127);
        }
        ::close(out[1]);
        FILE* f = ::fdopen(out[0], "r");
        char line[512];
        while (f && std::fgets(line, sizeof line, f)) {
            if (const char* at = std::strstr(line, "listening on http://")) {
                // The port follows the host's ':' (the rest of the line may hold more, a store URL's).
                const char* colon = std::strchr(at + std::strlen("listening on http://"), ':');
                port = colon ? std::atoi(colon + 1) : 0;
                break;
            }
        }
        if (port <= 0) throw std::runtime_error("cutload serve did not start (see its log above)");
        // Keep reading its stdout so the server never blocks on a full pipe.
        std::thread([f] {
            char buf[512];
            while (std::fgets(buf, sizeof buf, f)) {
            }
            std::fclose(f);
        }).detach();
    }
    ServerProcess(const ServerProcess&) = delete;
    ServerProcess& operator=(const ServerProcess&) = delete;
    ~ServerProcess() {
        if (pid > 0) {
            ::kill(pid, SIGTERM);
            ::waitpid(pid, nullptr, 0);
        }
    }
};

}  // namespace cutload::bench
