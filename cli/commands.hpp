// The cutload executable is one CLI11 app; each subcommand lives in its own cli/cmd_*.cpp and
// registers itself here, so adding a command touches no shared file.
#pragma once

#include "app/inputs.hpp"
#include "server/server.hpp"

#include <CLI/CLI.hpp>

#include <csignal>

#include <stdexcept>
#include <string>

namespace cutload::cli {

// Thrown by a command for bad input: main prints "cutload: error: <what>" and exits with code.
class UsageError : public std::runtime_error {
public:
    explicit UsageError(const std::string& what, int code = 2) : std::runtime_error(what), code_(code) {}
    int code() const { return code_; }
private:
    int code_;
};

using AddCommandFn = void (*)(CLI::App& app);

// Returns a dummy value so it can initialise a namespace-scope constant in each cmd_*.cpp.
bool register_command(const char* name, AddCommandFn add);

// Throws UsageError when `path` cannot be written as an output file (missing or unwritable
// folder, or a folder in its place), naming the option; checked before long computations.
void check_output_path(const std::string& path, const char* option);

// The log-format options shared by inspect, resample, predict and optimize:
//   --format csv|shdr|auto, --map FILE, --units mm|in, --feed-units UNIT
void add_log_options(CLI::App& sub, app::LogFormat& format);

// The reader's options from those and the resampling step; a bad value exits 2 naming the option.
motion_io::ReadOptions reader_options(const app::LogFormat& format, double step_ms = motion_io::ReadOptions{}.step_ms);

// Blocks SIGINT and SIGTERM for this thread and every thread it starts (they are then taken
// with sigwait / sigtimedwait, never in a handler) and ignores SIGPIPE; returns the set.
sigset_t block_stop_signals();

// HOST:PORT of a listen option into host and port; a bad value is a UsageError naming the option.
void split_listen(const std::string& listen, const char* option, std::string& host, int& port);

// --db and --data-dir of the commands that open the service's store (serve, worker).
void add_store_options(CLI::App& sub, server::ServerOptions& opt);

// What computing jobs takes, the same for serve and worker: --device, the work limits,
// --max-raw-rows, --no-limit-alerts, --drain-s, --max-attempts, --lease-s, --umask.
void add_job_options(CLI::App& sub, server::ServerOptions& opt, std::string& device);

// --max-force-rows, --max-stock-cells, --max-job-memory-mb (app::WorkLimits; docs/api.md, "Work limits").
void add_work_limit_options(CLI::App& sub, double& max_force_rows, double& max_stock_cells, double& max_job_memory_mb);

// The engine's device for --device opencl|cpu|auto; says on stderr when auto falls back to the CPU.
force_model::Device choose_device(const std::string& name);

}  // namespace cutload::cli
