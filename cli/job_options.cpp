// Options shared by the commands that compute jobs from a store: `cutload serve` and `cutload worker`.
#include "commands.hpp"

namespace cutload::cli {

void split_listen(const std::string& listen, const char* option, std::string& host, int& port) {
    const auto colon = listen.rfind(':');
    if (colon == std::string::npos || colon == 0)
        throw UsageError(std::string(option) + ": expected HOST:PORT, got '" + listen + "'");
    std::string h = listen.substr(0, colon);
    if (h.size() > 2 && h.front() == '[' && h.back() == ']') h = h.substr(1, h.size() - 2);
    int p = -1;
    try {
        std::size_t used = 0;
        p = std::stoi(listen.substr(colon + 1), &used);
        if (used != listen.size() - colon - 1) p = -1;
    } catch (const std::exception&) {
    }
    if (p < 0 || p > 65535)
        throw UsageError(std::string(option) + ": '" + listen.substr(colon + 1) + "' is not a port (0..65535)");
    host = h;
    port = p;
}

void add_store_options(CLI::App& sub, server::ServerOptions& opt) {
    sub.add_option("--db", opt.db_path,
                   "Store: SQLite file (created if missing) or postgresql://user:password@host:port/database (must exist)")
        ->capture_default_str();
    sub.add_option("--data-dir", opt.data_dir,
                   "Where uploaded logs are kept (default: <db>.data; required with PostgreSQL, the same folder for every process)");
}

void add_job_options(CLI::App& sub, server::ServerOptions& opt, std::string& device) {
    sub.add_option("--device", device, "Force engine device")->check(CLI::IsMember({"opencl", "cpu"}))->capture_default_str();
    add_work_limit_options(sub, opt.max_force_rows, opt.max_stock_cells, opt.max_job_memory_mb);
    sub.add_option("--max-raw-rows", opt.max_raw_rows,
                   "A run expecting more force rows stores envelopes (min/max per 8, 64, ... rows), not every row; 0: always every row")
        ->check(CLI::Range(0.0, 1e12))
        ->capture_default_str();
    sub.add_option("--checkpoint-every-s", opt.checkpoint_every_s,
                   "Seconds of motion between the stock checkpoints a run keeps, from which a window is recomputed "
                   "(at most 8 a run); 0: none")
        ->check(CLI::Range(0.0, 1e6))
        ->capture_default_str();
    sub.add_flag("!--no-limit-alerts", opt.limit_alerts,
                 "Do not raise an alert for blocks over the run's own limits (only thresholds raise alerts)");
    sub.add_option("--drain-s", opt.drain_s, "On shutdown, seconds running jobs may take before re-queueing")
        ->check(CLI::Range(0.0, 3600.0))
        ->capture_default_str();
    sub.add_option("--max-attempts", opt.max_attempts,
                   "Times one job may be claimed across crashes (of its process) before it is failed with the reason")
        ->check(CLI::Range(1, 100))
        ->capture_default_str();
    sub.add_option("--lease-s", opt.lease_s,
                   "Seconds a job's claim holds without renewal (renewed every third of it); on PostgreSQL a job whose "
                   "process died is re-queued this long after its last renewal")
        ->check(CLI::Range(0.3, 3600.0))
        ->capture_default_str();
    sub.add_option_function<std::string>(
           "--umask",
           [&opt](const std::string& text) {
               std::size_t used = 0;
               unsigned long mask = 0;
               try {
                   mask = std::stoul(text, &used, 8);
               } catch (const std::exception&) {
                   used = 0;
               }
               if (used != text.size() || mask > 0777)
                   throw CLI::ValidationError("--umask", "'" + text + "' is not an octal umask 000..777");
               opt.file_umask = static_cast<unsigned>(mask);
           },
           "Permission bits the database, uploads and folders are created without (octal; default 077: owner only)")
        ->default_str("077");
}

}  // namespace cutload::cli
