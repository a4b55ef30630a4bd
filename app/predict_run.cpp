#include "app/predict_run.hpp"
#include "app/tool_centre_point.hpp"
#include "app/workpiece_motion.hpp"

#include "rows_pipe.hpp"
#include "tracker.hpp"

#include "force_model/engine_settings.hpp"
#include "force_model/logged_commanded.hpp"
#include "force_model/streaming.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <numbers>
#include <optional>

namespace cutload::app {
namespace {

// Samples cut by a tool the table does not have get no forces: say how many, and which tools.
std::string unknown_tool_warning(const force_model::PredictStats& stats, std::size_t samples) {
    if (stats.unknown_tool_samples == 0) return {};
    std::string list;
    bool unnamed = false;
    for (int t : stats.unknown_tools) {
        if (t < 0) unnamed = true;
        else list += fmt::format("{}T{}", list.empty() ? "" : ", ", t);
    }
    if (unnamed) list += fmt::format("{}samples that name no tool", list.empty() ? "" : ", and ");
    const double share = 100.0 * double(stats.unknown_tool_samples) / double(std::max<std::size_t>(samples, 1));
    return fmt::format("{} samples ({:.1f} % of the log) run with a tool the run spec's table does not have ({}): no "
                       "forces are predicted for them and their blocks are flagged unknown_tool{}",
                       stats.unknown_tool_samples, share, list,
                       unnamed ? " (give the spec a \"tool\" for samples that name none, or a log or program that names "
                                 "the tools)"
                               : "");
}

// What of the tools can reach the stock: the widest cutter or holder of the spec.
ToolReach tool_reach(const force_model::RunSpec& spec) {
    ToolReach reach;
    reach.stock_box = spec.stock;
    for (int k = 0; k < 3; ++k) reach.offset_mm[std::size_t(k)] = spec.offset_mm[k];
    const auto widest = [](const force_model::ToolSpec& t) {
        return std::max(t.diameter_mm, t.holder.diameter_mm) / 2 + std::tan(t.taper_deg * std::numbers::pi / 180) * t.flute_length_mm;
    };
    const auto longest = [](const force_model::ToolSpec& t) { return t.stickout_mm + t.holder.length_mm; };
    reach.radius_mm = widest(spec.tool);
    reach.length_mm = longest(spec.tool);
    for (const force_model::NumberedTool& t : spec.tools) {
        reach.radius_mm = std::max(reach.radius_mm, widest(t.tool));
        reach.length_mm = std::max(reach.length_mm, longest(t.tool));
    }
    return reach;
}

// Frames within kFixedOrientationToleranceRad of each other are one (a log's quantised rotary
// axes put a second run at the same tilt microradians off).
double frame_angle_rad(const force_model::Rotation3& a, const force_model::Rotation3& b) {
    return orientation_angle_rad(tool_to_workpiece(a), tool_to_workpiece(b));
}
bool same_frame(const force_model::Rotation3& a, const force_model::Rotation3& b) {
    return frame_angle_rad(a, b) <= kFixedOrientationToleranceRad;
}

std::string frame_mismatch(const force_model::Rotation3& base, const ToolFrame& frame) {
    const double base_lean_deg = lean_from_z_rad(tool_to_workpiece(base).col(2)) * 180 / std::numbers::pi;
    return fmt::format("the base stock was cut with the tool leaning {:.4g} deg from the stock's +Z and this run's tool "
                       "leans {:.4g} deg ({:.4g} deg apart): a stock is kept in the frame of the tool that cut it, so a "
                       "run can start from it only at the same orientation (docs/five_axis.md, \"Fixed tilt\")",
                       base_lean_deg, frame.lean_deg, frame_angle_rad(base, frame.grid_from_stock()) * 180 / std::numbers::pi);
}

// The spec as the engine sees a fixed tilt: the offset turned into the tool's frame (the motion is
// turned there by workpiece_motion), the stock box the turned grid's (for the work estimate).
void turn_spec(force_model::RunSpec& spec, const force_model::Rotation3& g) {
    const Eigen::Vector3d o = tool_to_workpiece(g).transpose() * Eigen::Vector3d(spec.offset_mm[0], spec.offset_mm[1], spec.offset_mm[2]);
    for (int r = 0; r < 3; ++r) spec.offset_mm[r] = o[r];
    spec.stock = force_model::turned_stock_box(spec.stock, g, spec.resolution.grid_mm);
}

// A turning tool cuts the multi-direction stock: its three families' rays count as cells, all of
// them written.
void count_multi_direction_stock(WorkEstimate& work, const force_model::RunSpec& spec) {
    const double zmap_cells = work.stock_cells;
    work.stock_cells = force_model::multi_direction_stock_rays(spec.stock, spec.resolution.grid_mm);
    work.memory_mb += (force_model::multi_direction_stock_bytes(spec.stock, spec.resolution.grid_mm) -
                       zmap_cells * double(force_model::stock_bytes_per_cell())) /
                      (1024.0 * 1024.0);
}

// A window (RunInput::window) predicts its own rows only, and no commanded motion: at most its
// span at the log's top spindle speed, a row per motion sample in it, and the batches it starts
// and ends in (evaluated whole, their rows outside it dropped), not the whole log's. The log's motion, and with a
// program the commanded motion its mapping builds, still count.
void count_window(WorkEstimate& work, const force_model::TimeWindow& window, double step_s, bool rows_streamed) {
    const double span_s = std::clamp(window.to_s - window.from_s, 0.0, work.log_duration_s);
    const double rows = std::min(work.force_rows, span_s * work.spindle_max_rpm * 6 / work.angle_step_deg +
                                                      span_s / step_s + 2.0 * double(force_model::EngineSettings{}.max_batch_steps) + 2);
    const double held_before = rows_streamed ? work.commanded_rows : work.total_rows();
    const double held_after = rows_streamed ? 0 : rows;
    work.force_rows = rows;
    work.commanded_rows = 0;
    work.memory_mb += (held_after - held_before) * kJobBytesPerForceRow / (1024.0 * 1024.0);
    if (work.stocks > 1) {
        work.memory_mb -= double(work.stocks - 1) * work.stock_cells * double(force_model::stock_bytes_per_cell()) /
                          (1024.0 * 1024.0);
        work.stocks = 1;
    }
}

CuttingOrientation orientation_of(const ToolFrame& frame) {
    CuttingOrientation o;
    o.tilted = frame.tilted;
    o.lean_deg = frame.lean_deg;
    if (frame.tilted) o.grid_from_stock = frame.grid_from_stock();
    return o;
}

}  // namespace

InspectedLog inspect_run_log(const std::string& path, const motion_io::ReadOptions& read, const force_model::RunSpec& spec,
                             const machine::Machine* machine, double tool_length_mm) {
    InspectedLog out;
    std::optional<CuttingOrientationWatch> watch;
    if (machine) {
        try {
            watch.emplace(*machine, tool_length_mm, tool_reach(spec));
        } catch (const WorkpieceMotionError&) {
            // A machine no log can drive: check_log_axes says so.
        }
    }
    if (!watch) {
        out.report = motion_io::inspect(path, read);
        return out;
    }
    out.report = motion_io::inspect(path, read, [&](const motion_io::MotionState& s) { return watch->see(s); });
    out.orientation = orientation_of(watch->frame());
    return out;
}

WorkEstimate estimate_run_work(const motion_io::IngestReport& log, const force_model::RunSpec& spec,
                               const CuttingOrientation& orientation, const CommandedWork& commanded,
                               bool actual_rows_streamed) {
    if (!orientation.tilted) return estimate_work(log, spec, commanded, actual_rows_streamed);
    // Only the box and the grid count: the engine's cells of the box turned into the tool's frame.
    force_model::RunSpec turned = spec;
    turned.stock = force_model::turned_stock_box(spec.stock, orientation.grid_from_stock, spec.resolution.grid_mm);
    return estimate_work(log, turned, commanded, actual_rows_streamed);
}

// check_work, saying so when the stock's cells are the box turned into a tilted tool's frame (its
// grid covers the turned box, more cells than the box).
void check_run_work(const WorkEstimate& work, const WorkLimits& limits, const CuttingOrientation& orientation) {
    try {
        check_work(work, limits);
    } catch (const TooMuchWork& e) {
        if (!orientation.tilted || e.key() != "stock_cells") throw;
        const std::string why = std::string(e.what()).substr(e.key().size() + 2);   // what() is "key: why"
        throw TooMuchWork(e.key(), fmt::format("{} (the box turned into the frame of the tool leaning {:.4g} deg, whose "
                                               "grid covers it turned)",
                                               why, orientation.lean_deg));
    }
}

namespace {

// What every run says of the log it read (r.ingest, `samples` of motion): fewer than two samples
// are refused; coarse data is said out loud, never predicted from silently (docs/formats.md,
// "Coarse data"); rotary axes without a machine are taken as absent, and the user is told.
void check_log_read(const RunInput& in, std::size_t samples, RunResult& r) {
    if (samples < 2) throw motion_io::IngestError(in.log_path + ": the log holds fewer than two motion samples");
    r.sampling = motion_io::check_sampling(r.ingest, force_model::max_flutes(in.spec));
    if (!in.machine && !r.ingest.rotary_axes.empty())
        r.warnings.push_back(fmt::format("the log holds rotary axes ({}) but no machine definition was given: the tool "
                                         "is taken to move along x, y, z only (give the machine, e.g. --machine FILE)",
                                         r.ingest.rotary_axes));
}

// The device: the one prepare_device() chose, when it is choosing.
void take_device(const RunInput& in, force_model::PredictOptions& po, RunResult& r) {
    po.device = in.device;
    if (in.device_ready.valid()) {
        const DeviceChoice choice = in.device_ready.get();
        po.device = choice.device;
        r.device_note = choice.note;
    }
}

// A whole run's stock checkpoints into the folder, every `every_s` of motion at least. One that
// cannot be written is a warning, and no more are written after it.
void write_checkpoints(const CheckpointFolder& folder, std::uint64_t key, double actual_s, force_model::PredictOptions& po,
                       std::vector<std::string>& warnings) {
    po.checkpoint_every_s = std::max(folder.every_s, actual_s / kMaxCheckpoints);
    po.checkpoint = [&folder, key, &warnings, writing = true](const force_model::StockCheckpoint& at,
                                                              const force_model::Stock& stock) mutable {
        if (!writing) return;
        try {
            write_checkpoint(folder.dir, key, at, stock);
        } catch (const std::exception& e) {
            writing = false;
            warnings.push_back(fmt::format("the stock checkpoint at t = {:.3f} s was not kept ({}), nor any after it: "
                                           "windows of this run are recomputed from further back",
                                           at.t_s, e.what()));
        }
    };
}

// Samples a log's motion is read in when it is not kept whole (RunInput::keep_motion): 65 s at a
// 1 ms step, about 5 MB.
constexpr std::size_t kMotionPieceSamples = std::size_t(1) << 16;
constexpr std::size_t kProgressSamples = 2048;

// A run of the log alone whose motion is not kept: read twice in pieces, never whole. The first
// read gives what the job checks before it predicts (the report, the block names, the checkpoint
// key); the second is walked as it is read (force_model::StreamingPrediction at the WholeLog
// pace), the very rows, summaries, checkpoints and final stock predict() gives on the whole model.
RunResult predict_streamed(const RunInput& in, const Control& control) {
    Tracker track(control);
    RunResult r;
    r.motion_kept = false;
    track.begin(Phase::Ingest, 0, 0);
    motion_io::ReadOptions read = in.read;
    if (in.device_ready.valid() && in.device_ready.wait_for(std::chrono::seconds(0)) != std::future_status::ready)
        read.threads = 1;   // as predict_steps: PoCL is opening on the other core
    const bool checkpointing = in.checkpoints.has_value();
    force_model::CheckpointKey key;
    std::vector<std::string> block_names;
    double t0_s = 0, t1_s = 0;
    std::size_t sessions = 0;   // of the model (the report also counts those too short to keep)
    r.ingest = motion_io::ingest_in_pieces(
        in.log_path, read, kMotionPieceSamples,
        [&](const motion_io::MotionModel& piece, std::size_t first) {
            track.check();
            if (first == 0) t0_s = piece.t_s.front();
            t1_s = piece.t_s.back();
            sessions += piece.session_start.size();
            if (checkpointing) key.add(piece, first);
        },
        &block_names);
    const std::size_t samples = r.ingest.extent.samples;
    check_log_read(in, samples, r);
    r.work = estimate_run_work(r.ingest, in.spec, CuttingOrientation{}, CommandedWork{}, in.rows_out.has_value());
    check_run_work(r.work, in.limits, CuttingOrientation{});

    force_model::PredictOptions po;
    take_device(in, po, r);
    if (in.base_stock && !same_frame(force_model::stock_grid_frame(*in.base_stock), force_model::Rotation3{}))
        throw InputError("base_stock", frame_mismatch(force_model::stock_grid_frame(*in.base_stock), ToolFrame{}));
    po.base_stock = in.base_stock;
    po.keep_final_stock = in.keep_final_stock;
    po.cancel = control.cancel;
    po.max_rows = max_rows(in.limits);
    std::optional<RowsPipe> pipe;   // the rows' encoding and writing overlap the engine's walk
    if (in.rows_out) {
        if (in.rows_out->begin) in.rows_out->begin(block_names, r.work.force_rows);
        pipe.emplace([&](std::span<force_model::ForceSample> rows) { in.rows_out->rows(rows); });
        po.rows_out = [&](std::span<const force_model::ForceSample> rows) {
            r.rows += rows.size();
            pipe->push(rows);
        };
    }
    // As predict() writes them: for a log of one session.
    if (checkpointing && sessions == 1)
        write_checkpoints(*in.checkpoints, key.key(in.read.step_ms * 1e-3, in.spec, in.base_stock), t1_s - t0_s, po,
                          r.warnings);

    track.begin(Phase::Predict, 0, 1);
    force_model::StreamingPrediction engine(in.spec, po, force_model::StreamPace::WholeLog);
    force_model::StreamOutput out;
    // A log still being written gives more the second time: what was checked and named before
    // would not be what is walked.
    const auto changed = [&](std::size_t now_samples) {
        return motion_io::IngestError(fmt::format("{}: the log changed while it was read ({} motion samples the first "
                                                  "time, {} the second): predict it once it is complete",
                                                  in.log_path, samples, now_samples));
    };
    const motion_io::IngestReport second = motion_io::ingest_in_pieces(
        in.log_path, read, kMotionPieceSamples, [&](const motion_io::MotionModel& piece, std::size_t first) {
                                    if (first + piece.size() > samples || piece.block_names.size() > block_names.size())
                                        throw changed(first + piece.size());
                                    // A piece is a second or two of work: walked a part at a time,
                                    // progress moves and a cancel is seen within a fraction of that.
                                    for (std::size_t b = 0; b < piece.size(); b += kProgressSamples) {
                                        engine.add(piece, b, b + kProgressSamples);
                                        engine.advance(out);
                                        out.blocks.clear();   // finish() gives them all
                                        track.report(double(first + std::min(piece.size(), b + kProgressSamples)) /
                                                     double(samples));
                                    }
                                    if (in.motion_out) in.motion_out(piece);
                                });
    if (second.extent.samples != samples) throw changed(second.extent.samples);
    r.prediction = engine.finish(out);
    if (pipe) pipe->finish();
    r.prediction.samples = std::move(out.samples);
    r.rows += r.prediction.samples.size();
    r.motion.step_s = in.read.step_ms * 1e-3;
    r.motion.block_names = r.prediction.block_names;
    r.walked_from_s = t0_s;
    if (const std::string w = unknown_tool_warning(r.prediction.stats, samples); !w.empty()) r.warnings.push_back(w);
    track.done();
    return r;
}

RunResult predict_steps(const RunInput& in, const Control& control) {
    Tracker track(control);
    RunResult r;
    track.begin(Phase::Ingest, 0, 0);
    if (in.program && in.commanded_from_log)
        throw InputError("commanded_from_log", "the program and the log's commanded positions both give the commanded path: "
                                               "choose one");
    if (in.window && in.commanded_from_log)
        throw InputError("window", "a window is the logged motion's forces alone; the log's commanded path is compared "
                                   "over the whole run (drop the window or commanded_from_log)");
    if (in.window && in.machine)
        throw InputError("window", "a window of a run on a five-axis machine is not recomputed yet: predict the whole run");
    motion_io::ReadOptions read = in.read;
    // PoCL takes tens of ms to open (it loads LLVM) on a thread of its own: the second core is its
    // until then, and a scan thread beside it only delays both.
    if (in.device_ready.valid() && in.device_ready.wait_for(std::chrono::seconds(0)) != std::future_status::ready)
        read.threads = 1;
    r.motion = motion_io::ingest(in.log_path, read, &r.ingest);
    std::optional<MachineAxesForces> machine_axes;
    check_log_read(in, r.motion.size(), r);
    // The program is read in the machine's axes, from where the log's axes start.
    const std::optional<std::array<double, 3>> axes_start_mm = log_start_mm(r.motion);
    force_model::RunSpec spec = in.spec;   // in the tool's frame for a fixed tilt
    ToolFrame frame;
    // A tool that turns where it can reach the stock: its poses, for the multi-direction stock.
    std::optional<force_model::ToolPoses> turning;
    std::array<double, 3> axes_start_deg{};   // by axis letter, as the NC reader takes them
    if (in.machine) {
        if (in.commanded_from_log)
            throw InputError("machine", "a machine definition cannot be combined with the log's commanded path yet: "
                                        "predict the log alone, or with its NC program");
        try {
            axes_start_deg = rotary_start_by_letter(r.motion, *in.machine);
            motion_io::MotionModel axes = std::move(r.motion);
            bool turns = false;
            try {
                frame = tool_frame(axes, *in.machine, in.tool_length_mm, tool_reach(in.spec));
            } catch (const ToolTurnsInStock&) {
                turns = true;
            }
            if (turns) {
                TurningMotion t = turning_motion(axes, *in.machine, in.tool_length_mm);
                r.motion = std::move(t.motion);
                r.motion_tool_axis.reserve(t.poses.tool_to_stock.size());
                for (const force_model::Rotation3& R : t.poses.tool_to_stock)   // row-major: the axis is column 2
                    r.motion_tool_axis.push_back({float(R.m[2]), float(R.m[5]), float(R.m[8])});
                turning = std::move(t.poses);
                r.tool_lean_deg = t.max_lean_deg;
                r.turning = true;
            } else {
                if (frame.tilted) {
                    // A base stock cut at (about) this tilt keeps its frame, so the two runs share a grid.
                    if (in.base_stock && same_frame(force_model::stock_grid_frame(*in.base_stock), frame.grid_from_stock()))
                        frame.tool_to_workpiece = tool_to_workpiece(force_model::stock_grid_frame(*in.base_stock));
                    turn_spec(spec, frame.grid_from_stock());
                }
                r.motion = workpiece_motion(axes, *in.machine, in.tool_length_mm, frame);
            }
            // The machine axes stay for the rows' machine-axis forces (MachineAxesForces says why
            // they are taken at each row's time).
            machine_axes.emplace(std::move(axes), in.machine);
        } catch (const WorkpieceMotionError& e) {
            throw InputError("machine", e.what());
        }
        if (turning) {
            // It turns: the axis reported is the log's first sample's, the lean the largest.
            for (int k = 0; k < 3; ++k) r.tool_axis[std::size_t(k)] = turning->tool_to_stock.front().m[std::size_t(3 * k + 2)];
        } else {
            for (int k = 0; k < 3; ++k) r.tool_axis[std::size_t(k)] = frame.tool_to_workpiece(k, 2);
            r.tool_lean_deg = frame.lean_deg;
            r.fixed_tilt = frame.tilted;
        }
    }

    // Before predicting: a log without the program's block names takes them by mapping.
    std::optional<motion_io::NcProgram> machine_program;   // a turning tool's program, as read
    if (in.program) {
        track.begin(Phase::Program, 0, 0);
        ProgramSource source = *in.program;
        source.settings.limits.sample_step_s = r.motion.step_s;   // the commanded samples it may imply
        if (in.machine) {
            source.settings.rotary_axes = machine_rotary_axes(*in.machine);
            source.settings.start_deg = axes_start_deg;
            source.settings.tool_centre_point = tool_centre_point_kinematics(in.machine, in.tool_length_mm);
        }
        motion_io::NcProgram program = read_program(source, in.spec, axes_start_mm);
        // With a machine: the tip's commanded path against the part (stock axes), its orientation
        // held to the log's rule; a turning tool's commanded run is made from the machine axes.
        if (turning) {
            machine_program = program;
            program = turning_workpiece_program(program, *in.machine, in.tool_length_mm, source.settings.rapid_mm_min);
        } else if (in.machine) {
            program = workpiece_program(program, *in.machine, in.tool_length_mm, source.settings.rapid_mm_min, {}, frame,
                                        tool_reach(in.spec));
        }
        // Without a tool table the run spec's one tool cuts every block; say so when the program
        // changes tools. (With a table, tools it lacks are counted after the prediction.)
        if (const std::vector<int> tools = motion_io::program_tools(program); tools.size() > 1 && in.spec.tools.empty()) {
            std::string list;
            for (int t : tools) list += fmt::format("{}T{}", list.empty() ? "" : ", ", t);
            r.warnings.push_back(fmt::format("the program uses tools {}; forces are predicted with the run spec's one tool "
                                             "for every block (give the spec a tool table, \"tools\", to predict each "
                                             "block with its own)",
                                             list));
        }
        CommandedWork commanded;
        commanded.program = &program;
        commanded.options.step_s = r.motion.step_s;
        commanded.options.rapid_mm_min = source.settings.rapid_mm_min;
        r.work = estimate_run_work(r.ingest, in.spec, orientation_of(frame), commanded, in.rows_out.has_value());
        if (turning) count_multi_direction_stock(r.work, in.spec);
        if (in.window) count_window(r.work, *in.window, r.motion.step_s, in.rows_out.has_value());
        check_run_work(r.work, in.limits, orientation_of(frame));
        track.begin(Phase::Mapping, 0, 0);
        // The log is matched to the program where both are: in stock axes (a tilted tool's motion
        // is in its own frame until the prediction is done). Its positions and velocities are put
        // back as they were, bit for bit (a turn there and back is not): the prediction must not
        // depend on whether a program came with the log.
        std::optional<std::array<std::vector<double>, 6>> in_frame;
        if (frame.tilted) {
            in_frame.emplace(std::array<std::vector<double>, 6>{r.motion.x_mm, r.motion.y_mm, r.motion.z_mm, r.motion.vx_mm_s,
                                                                r.motion.vy_mm_s, r.motion.vz_mm_s});
            turn_motion(r.motion, frame.tool_to_workpiece);
        }
        r.program = prepare_program_run(std::move(program), source.settings, r.motion, control);
        if (in_frame) {
            auto& [x, y, z, vx, vy, vz] = *in_frame;
            r.motion.x_mm = std::move(x), r.motion.y_mm = std::move(y), r.motion.z_mm = std::move(z);
            r.motion.vx_mm_s = std::move(vx), r.motion.vy_mm_s = std::move(vy), r.motion.vz_mm_s = std::move(vz);
        }
    } else {
        CommandedWork commanded;
        commanded.from_log = in.commanded_from_log;
        r.work = estimate_run_work(r.ingest, in.spec, orientation_of(frame), commanded, in.rows_out.has_value());
        if (turning) count_multi_direction_stock(r.work, in.spec);
        if (in.window) count_window(r.work, *in.window, r.motion.step_s, in.rows_out.has_value());
        check_run_work(r.work, in.limits, orientation_of(frame));
    }
    motion_io::MotionModel logged_commanded;
    if (in.commanded_from_log) {
        if (!r.ingest.commanded_positions)
            throw motion_io::IngestError(in.log_path + ": the log has no commanded positions (x_cmd, y_cmd, z_cmd, or the "
                                                       "columns a channel map names for them)");
        motion_io::ReadOptions commanded_read = in.read;
        commanded_read.positions = motion_io::Positions::Commanded;
        logged_commanded = motion_io::ingest(in.log_path, commanded_read);
        if (logged_commanded.size() < 2)
            throw motion_io::IngestError(in.log_path + ": the log's commanded positions give fewer than two motion samples");
    }

    // The commanded prediction follows the actual one; they share the progress by duration.
    double actual_share = 1;
    const double actual_s = r.motion.t_s.back() - r.motion.t_s.front();
    if (r.program) {
        double commanded_s = 0;
        for (double d : motion_io::commanded_durations_s(r.program->program, r.program->commanded)) commanded_s += d;
        actual_share = actual_s / std::max(1e-9, actual_s + commanded_s);
    } else if (in.commanded_from_log) {
        actual_share = 0.5;   // the same log twice
    }
    force_model::PredictOptions po;
    po.window = in.window;
    take_device(in, po, r);
    // The stock lies in the engine's frame: a base stock must have been cut in it.
    const force_model::Rotation3 grid_frame = frame.tilted ? frame.grid_from_stock() : force_model::Rotation3{};
    if (in.base_stock && !same_frame(force_model::stock_grid_frame(*in.base_stock), grid_frame))
        throw InputError("base_stock", frame_mismatch(force_model::stock_grid_frame(*in.base_stock), frame));
    // A turned stock is made for this run and handed over (not copied: it is written whole, unlike
    // a fresh box's zero pages, and the work estimate counts one stock).
    force_model::StockPtr turned;
    if (frame.tilted && !in.base_stock) {
        try {
            turned = force_model::make_turned_stock(in.spec.stock, grid_frame, spec.resolution.grid_mm);
        } catch (const std::invalid_argument& e) {
            throw InputError("stock", fmt::format("the stock box turned into the frame of the tool leaning {:.4g} deg: {}",
                                                  frame.lean_deg, e.what()));
        }
        po.own_stock = &turned;
    }
    po.base_stock = in.base_stock;
    po.keep_final_stock = in.keep_final_stock;
    po.cancel = control.cancel;
    // The job's rows together: the commanded prediction gets what the actual one left.
    po.max_rows = max_rows(in.limits);
    track.begin(Phase::Predict, 0, actual_share);
    po.progress = track.engine_progress();
    std::size_t rows_out = 0;
    std::optional<RowsPipe> pipe;   // the rows' encoding and writing overlap the engine's walk
    if (in.rows_out) {
        if (in.rows_out->begin) in.rows_out->begin(r.motion.block_names, r.work.force_rows);
        pipe.emplace([&](std::span<force_model::ForceSample> rows) {
            if (frame.tilted) turn_forces(rows, frame.tool_to_workpiece);
            if (machine_axes) machine_axes->apply(rows);
            in.rows_out->rows(rows);
        });
        po.rows_out = [&](std::span<const force_model::ForceSample> rows) {
            rows_out += rows.size();
            pipe->push(rows);
        };
    }
    // The engine says where each session's rows begin: their times alone cannot (sessions may
    // overlap in time).
    // With the rows on the pipe's thread, the session's start goes there too, in order with them.
    if (machine_axes)
        po.session_begins = [&](std::size_t begin, std::size_t end, std::size_t first_row) {
            if (pipe) pipe->post([&machine_axes, begin, end, first_row] { machine_axes->begin_session(begin, end, first_row); });
            else machine_axes->begin_session(begin, end, first_row);
        };
    // Stock checkpoints: a whole run writes them, a window resumes at the last one before it.
    const bool checkpointing = in.checkpoints && !in.machine;
    const std::uint64_t key = checkpointing ? force_model::checkpoint_key(r.motion, spec, in.base_stock) : 0;
    if (checkpointing && !in.window) write_checkpoints(*in.checkpoints, key, actual_s, po, r.warnings);
    force_model::StockPtr resume_stock;
    std::optional<CheckpointFile> resume_at;
    if (checkpointing && in.window) {
        resume_at = checkpoint_before(in.checkpoints->dir, key, in.window->from_s);
        if (resume_at) {
            try {
                resume_stock = read_checkpoint(*resume_at);
                po.base_stock = resume_stock.get();
                po.resume = resume_at->at;
            } catch (const std::exception& e) {   // bad_alloc too: a corrupt header may ask for any size
                r.warnings.push_back(fmt::format("stock checkpoint {} not used ({}): the window was walked from the log's start",
                                                 resume_at->path.filename().string(), e.what()));
                resume_at.reset();
            }
        }
    }
    auto predict_actual = [&] {
        return turning ? force_model::predict_turning(r.motion, *turning, spec, po) : force_model::predict(r.motion, spec, po);
    };
    try {
        r.prediction = predict_actual();
    } catch (const force_model::SpecError& e) {
        // Refused before any row: a checkpoint that does not fit is a cache miss.
        if (!po.resume) throw;
        r.warnings.push_back(fmt::format("stock checkpoint {} not used ({}): the window was walked from the log's start",
                                         resume_at->path.filename().string(), e.what()));
        resume_at.reset();
        po.resume.reset();
        po.base_stock = in.base_stock;
        r.prediction = predict_actual();
    }
    r.resumed = resume_at.has_value();
    r.walked_from_s = resume_at ? resume_at->at.t_s : r.motion.t_s.front();
    if (pipe) pipe->finish();
    if (frame.tilted) {
        turn_forces(r.prediction.samples, frame.tool_to_workpiece);
        turn_motion(r.motion, frame.tool_to_workpiece);   // the caller sees the motion in stock axes
    }
    if (machine_axes) machine_axes->apply(r.prediction.samples);
    po.own_stock = nullptr;
    po.rows_out = nullptr;   // the commanded prediction's rows stay in its result
    po.session_begins = nullptr;
    po.checkpoint = nullptr;   // the commanded prediction's stock is no state of the run's
    r.rows = rows_out + r.prediction.samples.size();
    if (po.max_rows > 0) po.max_rows = std::max<std::size_t>(1, po.max_rows - std::min(po.max_rows, r.rows));
    if (const std::string w = unknown_tool_warning(r.prediction.stats, r.motion.size()); !w.empty()) r.warnings.push_back(w);
    if (in.window) {
        // A window is the actual motion's forces alone: the comparison is the whole run's.
    } else if (r.program) {
        track.begin(Phase::Commanded, actual_share, 1);
        po.progress = track.engine_progress();
        // A tilted tool's commanded run cuts its own turned stock, in the same frame as the actual.
        force_model::StockPtr commanded_stock;
        if (frame.tilted && !in.base_stock) {
            commanded_stock = force_model::make_turned_stock(in.spec.stock, grid_frame, spec.resolution.grid_mm);
            po.own_stock = &commanded_stock;
        }
        const TurningCommand turning_command{machine_program ? &*machine_program : nullptr, in.machine.get(), in.tool_length_mm};
        r.commanded = predict_program(*r.program, r.motion, r.prediction, spec, po, frame.tilted ? &grid_frame : nullptr,
                                      machine_program ? &turning_command : nullptr);
        po.own_stock = nullptr;
    } else if (in.commanded_from_log) {
        track.begin(Phase::Commanded, actual_share, 1);
        po.progress = track.engine_progress();
        ProgramPrediction p;
        p.commanded = force_model::predict(logged_commanded, in.spec, po);
        p.blocks = force_model::compare_logged_commanded(r.motion, logged_commanded, p.commanded, r.prediction);
        // Both read from one log: one time axis.
        p.to_actual_time.commanded_s = p.to_actual_time.actual_s = {r.motion.t_s.front(), r.motion.t_s.back()};
        r.commanded_samples = logged_commanded.size();
        r.commanded = std::move(p);
    }
    track.done();
    return r;
}

}  // namespace

RunResult predict_run(const RunInput& in, const Control& control) {
    return cancellable(control, [&] {
        try {
            // The motion is needed whole to map a program onto it, to compare it with a commanded
            // path, to turn it through a machine's kinematics, and to walk a window.
            const bool stream = !in.keep_motion && !in.program && !in.commanded_from_log && !in.machine && !in.window;
            return stream ? predict_streamed(in, control) : predict_steps(in, control);
        } catch (const force_model::TooManyRows& e) {
            throw TooMuchWork("force_rows", fmt::format("{} (--max-force-rows)", e.what()));
        }
    });
}

}  // namespace cutload::app
