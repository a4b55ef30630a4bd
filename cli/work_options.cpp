// The work limits' options, the same for `cutload predict` and `cutload serve`.
#include "commands.hpp"

namespace cutload::cli {

void add_work_limit_options(CLI::App& sub, double& max_force_rows, double& max_stock_cells, double& max_job_memory_mb) {
    sub.add_option("--max-force-rows", max_force_rows,
                   "Most force rows a run's predictions may write together (estimated before it starts)")
        ->check(CLI::Range(1.0, 1e12))
        ->capture_default_str();
    sub.add_option("--max-stock-cells", max_stock_cells, "Most dexel cells of a run's stock (box / grid_mm squared)")
        ->check(CLI::Range(1.0, 4e8))
        ->capture_default_str();
    sub.add_option("--max-job-memory-mb", max_job_memory_mb, "Most memory a run is estimated to need, MiB")
        ->check(CLI::Range(1.0, 1e7))
        ->capture_default_str();
}

}  // namespace cutload::cli
