// Use case: predict a run. A dry-run log and its run spec, optionally the NC program the log runs
// and the stock an earlier run left, give the forces of the actual motion, the block summaries
// with their flags, the final stock, and with a program the forces of the commanded motion
// compared block by block with the actual ones.
#pragma once

#include "app/checkpoints.hpp"
#include "app/control.hpp"
#include "app/inputs.hpp"
#include "app/program_run.hpp"
#include "app/program_source.hpp"
#include "app/work_bounds.hpp"
#include "force_model/force_model.hpp"
#include "force_model/program_compare.hpp"
#include "motion_io/motion_io.hpp"

#include <array>
#include <cstddef>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace cutload::machine {
struct Machine;   // machine/machine.hpp (kept out of this header: front ends need not see Eigen)
}

namespace cutload::app {

struct RunInput {
    std::string log_path;
    motion_io::ReadOptions read;                      // read_options(): format, units, resampling step
    force_model::RunSpec spec;
    std::optional<ProgramSource> program;             // the NC program the log is a dry run of
    bool commanded_from_log = false;                  // or the log's own commanded positions as the commanded path
    const force_model::Stock* base_stock = nullptr;   // start from it (load_stock, load_stock_bytes)
    force_model::Device device = force_model::Device::Cpu;
    // When valid: the device prepare_device() is choosing, taken once the log is read (it replaces
    // `device`; its note goes to RunResult::device_note).
    std::shared_future<DeviceChoice> device_ready;
    WorkLimits limits;                                // checked before predicting (TooMuchWork)
    // Where the actual prediction's rows go as they become final, when set: RunResult's
    // prediction.samples then stays empty and memory does not grow with the log's length.
    // begin() gets the names the rows' block indices refer to and the rows expected at most
    // (force_model::expected_rows), once, before the first rows.
    struct RowsOut {
        std::function<void(const std::vector<std::string>& block_names, double expected_rows)> begin;
        std::function<void(std::span<const force_model::ForceSample> rows)> rows;
    };
    std::optional<RowsOut> rows_out;
    // False when nothing will use RunResult's final stocks (no --save-stock): a GPU then reads none
    // of the stock back.
    bool keep_final_stock = true;
    // The machine the log was recorded on (five-axis, docs/five_axis.md): its axes then go
    // through forward kinematics (workpiece_motion.hpp) before the engine; tool_length_mm is the
    // gauge point to the tip. Absent: the log's x, y, z are the tool tip, as on a three-axis machine.
    // With a machine every row also gets its forces in machine axes (ForceSample::fx_machine_N ...,
    // MachineAxesForces), in rows_out and in RunResult's prediction alike.
    std::shared_ptr<const machine::Machine> machine;
    double tool_length_mm = 0;
    // When set: only this stretch of the log's time is predicted, at full resolution, the very
    // rows a whole run gives there (force_model::PredictOptions::window; the motion before it is
    // walked for its removal alone). A program still names the blocks; the commanded prediction
    // and the comparison are not made. Refused (InputError "window") with commanded_from_log or a
    // machine; a log of several sessions, an empty window or one outside the log are SpecErrors.
    std::optional<force_model::TimeWindow> window;
    // Stock checkpoints (checkpoints.hpp; not with a machine): a whole run writes its own into the
    // folder, a window resumes its walk at the last one of the same run at or before its start
    // (RunResult::walked_from_s). One that cannot be written or read is a warning, never an error.
    std::optional<CheckpointFolder> checkpoints;
    // False: the log's motion is not held whole. A run of the log alone (no program, no
    // commanded_from_log, no machine, no window: each needs the motion whole, and keeps it) is then
    // read in pieces, twice: once for the checks made before predicting, once walked as it is read,
    // so its memory does not grow with the log's length (docs/force_model.md, "Streaming a log").
    // RunResult::motion then holds no samples (motion_kept false) and motion_out, when set, gets
    // each piece once the engine has it. The rows, summaries, checkpoints and final stock are the
    // same either way.
    bool keep_motion = true;
    std::function<void(const motion_io::MotionModel& piece)> motion_out;
};

// A machine definition file (docs/machines.md), with the errors of an errors file when one is
// given; a bad file is an InputError("machine" or "machine_errors") whose message names the key.
std::shared_ptr<const machine::Machine> load_machine_definition(const std::string& path,
                                                               const std::string& errors_path = "");
// The same, with the files named in messages as the user knows them: a service names the parts a
// client uploaded ("part kinematics"), never the paths it stored them at.
struct MachineFiles {
    std::string path;            // the definition
    std::string errors_path;     // its geometric errors; empty: none
    std::string shown_as;        // how messages name each; empty: by its path
    std::string errors_shown_as;
};
std::shared_ptr<const machine::Machine> load_machine_definition(const MachineFiles& files);
// A log whose rotary axes (IngestReport::rotary_axes: "ac", as inspect and ingest report them)
// lack one the machine needs: InputError("machine") naming the axis and its column, the message
// predict_run gives once it has ingested such a log. Cheap, so a front end can refuse at upload,
// from the inspect report, what the job would refuse.
void check_log_axes(const machine::Machine& machine, const std::string& log_rotary_axes);
// Its rotary axes as the NC reader takes them (ProgramSettings::rotary_axes): "AC"
// (workpiece_motion.hpp; declared here for front ends, which do not see the machine).
std::string machine_rotary_axes(const machine::Machine& machine);

// The orientation a log's tool cuts at, as a front end sees it (no Eigen): a fixed tilt (3+2
// work) lays the stock out in the tool's frame, whose grid covers the box turned, so the work a run
// implies depends on it (docs/five_axis.md, "Fixed tilt").
struct CuttingOrientation {
    bool tilted = false;
    double lean_deg = 0;                    // the tool axis from the stock's +Z
    force_model::Rotation3 grid_from_stock;  // the engine's frame (the identity unless tilted)
};

// The log read as the job will read it (inspect_log: streamed, memory does not grow with the log)
// and, with a machine, the orientation its tool cuts at by the job's rule (tool_frame: the nominal
// pose at the first sample where a tool of the spec can reach the stock; one forward call a sample
// until then). What the job checks further (that the tool keeps that orientation there) it still
// checks; a machine whose axes the log cannot give leaves the orientation vertical (check_log_axes
// refuses such a log). Throws what inspect_log throws.
struct InspectedLog {
    motion_io::IngestReport report;
    CuttingOrientation orientation;
};
InspectedLog inspect_run_log(const std::string& path, const motion_io::ReadOptions& read, const force_model::RunSpec& spec,
                             const machine::Machine* machine, double tool_length_mm);

// estimate_work with the stock box the engine lays out at `orientation` (turned for a fixed tilt),
// and check_work saying so in a stock_cells refusal: what the job estimates and checks, so an upload
// that knows the orientation refuses with the job's figures.
WorkEstimate estimate_run_work(const motion_io::IngestReport& log, const force_model::RunSpec& spec,
                               const CuttingOrientation& orientation, const CommandedWork& commanded = {},
                               bool actual_rows_streamed = false);
void check_run_work(const WorkEstimate& estimate, const WorkLimits& limits, const CuttingOrientation& orientation);

struct RunResult {
    motion_io::MotionModel motion;               // the repaired log; blocks named after the program's when mapped
    bool motion_kept = true;                     // false: streamed (RunInput::keep_motion), `motion` has no samples
    motion_io::IngestReport ingest;
    force_model::Prediction prediction;          // forces, block summaries and flags, final stock, stats
    motion_io::SamplingCheck sampling;           // coarse data (position_quantized, sampling_coarse), said out loud
    std::vector<std::string> warnings;           // for the user: e.g. a program with more than one tool
    std::string device_note;                     // RunInput::device_ready fell back to the CPU: why
    std::optional<ProgramRun> program;           // with a program: it, and its mapping onto the log
    std::optional<ProgramPrediction> commanded;  // with a program or commanded_from_log: commanded forces,
                                                 // comparison, time warp (identity for the log's own)
    std::size_t commanded_samples = 0;           // commanded_from_log: samples of the commanded motion
    WorkEstimate work;                           // the work estimated before predicting
    std::size_t rows = 0;                        // rows of the actual prediction (also those sent to rows_out)
    // Where the actual prediction's walk began: the log's start, or with a window the stock
    // checkpoint it resumed at (RunInput::checkpoints).
    double walked_from_s = 0;
    bool resumed = false;
    // With a machine: the tool's axis where it cuts, in stock coordinates (unit, tip to spindle),
    // and its lean from +Z. A tool leaning more than kFixedOrientationToleranceRad was predicted
    // in its own frame (a fixed tilt, docs/five_axis.md); motion and forces come back in stock axes.
    std::array<double, 3> tool_axis{0, 0, 1};
    double tool_lean_deg = 0;
    bool fixed_tilt = false;
    // The tool turned where it could reach the stock (simultaneous five-axis work): predicted on the
    // multi-direction stock (force_model::predict_turning); tool_axis is then the log's first
    // sample's and tool_lean_deg the largest lean over the log. FORCES rows carry the axis per row.
    bool turning = false;
    // A turning tool's axis at each sample of `motion` (unit, tip to spindle, stock axes: the poses
    // the engine cut with, forward kinematics with the machine's errors); empty for any other run,
    // whose axis is tool_axis throughout. The service stores it beside the motion (/motion's
    // tool_axis_x, _y, _z) for the web page's 3-D view.
    std::vector<std::array<float, 3>> motion_tool_axis;
};

// Phases: Ingest, then with a program Program and Mapping, Predict, with a commanded path
// Commanded, Done. The two predictions share the progress by their simulated durations. Throws
// InputError when both a program and commanded_from_log are given, motion_io::IngestError (a bad
// log, one of fewer than two samples, or commanded_from_log on a log without commanded
// positions), motion_io::NcProgramError (a bad program, or one the log does not run),
// force_model::SpecError, force_model::Cancelled, and TooMuchWork when the work the log, spec and
// program imply passes input.limits (checked once the program is read, before mapping and
// predicting; the engine stops at the row limit should the estimate be low).
RunResult predict_run(const RunInput& input, const Control& control = {});

}  // namespace cutload::app
