// What every benchmark measures with: CPU time of the process, peak memory, the load average (the
// machine is shared, so every figure is printed with it) and medians of repeated runs.
#pragma once

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

namespace cutload::bench {

inline double cpu_seconds() {
    rusage u{};
    getrusage(RUSAGE_SELF, &u);
    return double(u.ru_utime.tv_sec + u.ru_stime.tv_sec) + 1e-6 * double(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

// Peak resident memory of the process so far.
inline double peak_rss_mb() {
    rusage u{};
    getrusage(RUSAGE_SELF, &u);
    return double(u.ru_maxrss) / 1024.0;
}

inline std::string load_average() {
    std::ifstream in("/proc/loadavg");
    std::string one, five, fifteen;
    in >> one >> five >> fifteen;
    return one.empty() ? "unknown" : one + " " + five + " " + fifteen;
}

inline double median(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v.empty() ? 0.0 : v[v.size() / 2];
}

struct Timing {
    double wall_s = 0, cpu_s = 0;   // medians; CPU time shows the cost when the shared machine is busy
};

// Runs f `runs` times; the medians of its wall and CPU time.
template <class F>
Timing median_seconds(int runs, F&& f) {
    std::vector<double> wall, cpu;
    for (int i = 0; i < runs; ++i) {
        const auto t0 = std::chrono::steady_clock::now();
        const double c0 = cpu_seconds();
        f();
        cpu.push_back(cpu_seconds() - c0);
        wall.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    }
    return {median(wall), median(cpu)};
}

// A command run as a child process: its wall time, CPU time (user + system) and peak resident
// memory (wait4's ru_maxrss), and its exit status (-1 when it did not exit normally).
struct ChildRun {
    double wall_s = 0, cpu_s = 0, peak_rss_mb = 0;
    int status = -1;
};

// Runs args[0] with args, its stdout into `stdout_path` (its own output is not what is measured)
// and its stderr discarded.
inline ChildRun run_child(const std::vector<std::string>& args, const std::string& stdout_path = "/dev/null",
                          const std::string& stderr_path = "/dev/null") {
    std::vector<char*> argv;
    for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    ChildRun r;
    std::fflush(nullptr);   // or the child's copy of the buffered output is written twice
    const auto t0 = std::chrono::steady_clock::now();
    const pid_t pid = fork();
    if (pid == 0) {
        if (std::freopen(stdout_path.c_str(), "w", stdout) == nullptr || std::freopen(stderr_path.c_str(), "w", stderr) == nullptr)
            _exit(126);
        execv(argv[0], argv.data());
        _exit(127);
    }
    if (pid < 0) return r;
    int status = 0;
    rusage u{};
    if (wait4(pid, &status, 0, &u) != pid) return r;
    r.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    r.cpu_s = double(u.ru_utime.tv_sec + u.ru_stime.tv_sec) + 1e-6 * double(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
    r.peak_rss_mb = double(u.ru_maxrss) / 1024.0;
    r.status = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    return r;
}

}  // namespace cutload::bench
