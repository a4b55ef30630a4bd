// Every job is bounded before it starts: the work a log, its run spec and an NC program imply
// (force rows, stock cells, memory) is estimated from what is known before predicting (the log's
// inspect or ingest report, the spec, the program) and checked against limits the machine can
// honour. The CLI (cutload predict) and the service (at upload, and again in the job) check the
// same figures with the same messages; the engine counts its rows again as it writes them
// (force_model::PredictOptions::max_rows), so an estimate that is ever too low cannot run away.
#pragma once

#include "app/inputs.hpp"
#include "force_model/force_model.hpp"
#include "motion_io/commanded.hpp"
#include "motion_io/motion_io.hpp"
#include "motion_io/nc_program.hpp"

#include <cstddef>
#include <string>

namespace cutload::app {

// The defaults suit the smallest machine cutload is run on (2 cores, 8 GB, two jobs at once):
// docs/api.md, "Work limits", gives the figures they come from.
struct WorkLimits {
    // Rows of the job's predictions together (--max-force-rows): the actual prediction's rows are
    // streamed (RunInput::rows_out) so they bound the job's time and output, not its memory; about
    // two hours of cutting at 10000 rpm and 2 deg steps.
    double max_force_rows = 2e8;
    double max_stock_cells = 20e6;      // dexel cells of the stock (--max-stock-cells)
    double max_job_memory_mb = 3000;    // the estimate below (--max-job-memory-mb)
};

// What one force row, one stock cell and one motion sample cost a job at its peak, in bytes
// (measured figures and their derivation: docs/api.md, "Work limits").
//
// A held row (the commanded prediction's; the actual one's are streamed) peaks in the engine, at
// the moment its row vectors double past their reserve: the rows twice (the old buffer and the
// new one it is copied to) and the 24 B the engine keeps beside each (force_model's RowExtra),
// 2 x 96 + 24 = 216 B (the row was 80 B before it carried the tool axis). Measured with `cutload serve` (one worker, CPU path, SQLite) on the demo
// and its program at 0.2 and 0.1 deg (4.20e6 and 8.41e6 commanded rows, each just past a
// doubling, at 2^22 and 2^23 rows): peak RSS less 184 B for each row at the doubling leaves 73.1
// and 74.0 MB, the same fixed cost both times; below the reserve a row costs 137.5 B (0.5 to 0.25
// deg: the rows and the series built from them while the run is stored); those figures are of
// 80 B rows, and the doubling's share scales with the row's size. Taken from the struct's
// size, so a ForceSample that grows again is followed here.
inline constexpr double kJobBytesPerForceRow = 2.0 * sizeof(force_model::ForceSample) + 24;
inline constexpr double kJobBytesPerMotionSample = 200;
// Beyond the stocks themselves (force_model::stock_bytes_per_cell() each): the final stock as
// stored, about 40 B a cell (32 B per ray, 24 B per sub-cell wall), twice while it is written:
// the serialized bytes and the database's own copy of them.
inline constexpr double kJobBytesPerStoredCell = 80;

// The commanded motion a job predicts besides the log's: none, the program's, or the log's own
// commanded positions (the same extent as the log again).
struct CommandedWork {
    const motion_io::NcProgram* program = nullptr;
    motion_io::CommandedOptions options;   // the log's step, the rapid rate
    bool from_log = false;
};

struct WorkEstimate {
    double log_duration_s = 0;
    double spindle_max_rpm = 0;
    double spindle_revolutions = 0;    // of the log's motion
    double angle_step_deg = 0;
    double force_rows = 0;             // of the log's motion (force_model::expected_rows)
    double commanded_duration_s = 0;
    double commanded_revolutions = 0;
    double commanded_rows = 0;         // of the commanded motion; 0 without one
    double motion_samples = 0;         // the log's and the commanded motion's
    double stock_cells = 0;
    int stocks = 1;                    // stocks predicted on (the commanded motion cuts its own)
    double memory_mb = 0;
    double total_rows() const { return force_rows + commanded_rows; }
};

// `log` is the report of the log as the job reads it (inspect or ingest, same read options).
// `actual_rows_streamed`: the actual prediction's rows leave as they come (RunInput::rows_out), so
// they cost no memory (the commanded prediction's still do).
WorkEstimate estimate_work(const motion_io::IngestReport& log, const force_model::RunSpec& spec,
                           const CommandedWork& commanded = {}, bool actual_rows_streamed = false);

// Too much work for the limits: key() names the quantity (force_rows, stock_cells, job_memory),
// what() is "<key>: <the figures that give it, the limit and its option>".
class TooMuchWork : public InputError {
public:
    using InputError::InputError;
};

// Throws TooMuchWork for the first limit the estimate passes: stock cells, force rows, memory.
void check_work(const WorkEstimate& estimate, const WorkLimits& limits);

// The engine's own bound on the rows it may write (force_model::PredictOptions::max_rows).
std::size_t max_rows(const WorkLimits& limits);

}  // namespace cutload::app
