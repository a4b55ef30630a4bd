// Public interface of motion_io: read a dry-run motion log (CSV or MTConnect SHDR), repair its
// unequal sampling and hand the force engine a uniform, C1-continuous motion model.
//
// Ingest is a pipeline of small named stages (see docs/ingest.md):
//   parse -> validate -> align channels -> drop stale repeats -> smooth -> resample -> attribute blocks
#pragma once

#include <nlohmann/json_fwd.hpp>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <array>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace cutload::motion_io {

enum class Format { Auto, Csv, Shdr };

// Which positions of a log become the motion: the actual ones (what the machine did), or the
// commanded ones (the interpolator's output, x_cmd/y_cmd/z_cmd or the map's) where a log has both.
enum class Positions { Actual, Commanded };

struct ReadOptions {
    Format format = Format::Auto;
    // Channel map (JSON, docs/formats.md): CSV column names or SHDR keys per channel, units, and
    // sample_period_ms for CSV exports without a time column. A file path or the name of a
    // bundled preset (map_presets()); empty: built-in defaults.
    std::string map_file;
    Positions positions = Positions::Actual;
    std::optional<std::string> length_unit; // "mm" | "in": overrides the log's position/feed length unit
    std::optional<std::string> feed_unit;   // e.g. "mm/min", "mm/s", "in/min": explicit override for
                                            // logs whose feed values disagree with their declaration
    double step_ms = 1.0;                   // uniform resampling step of the motion model
    // Threads ingest may use (the clock stage's search for the CNC's update period): 2, or 1 where
    // another thread needs the second core (predict, while the OpenCL device opens). The same
    // motion either way.
    unsigned threads = 2;
};

// A bad log: names where (file, line, column or key) and what was expected.
class IngestError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

struct IntervalStats {
    double min_s = 0, median_s = 0, max_s = 0;
};

struct ChannelReport {
    std::size_t samples = 0;
    IntervalStats interval;
    double update_period_s = 0;      // estimated CNC update grid (0: not estimated)
    std::size_t stale_dropped = 0;   // repeated (not updated) readings removed
};

struct IngestWarning {
    std::string code;       // e.g. "gap", "stale_repeat", "time_backwards", "out_of_range"
    std::string message;    // human-readable, names where
    std::size_t count = 0;
};

// The repaired motion's extent, what the force engine walks: its uniform samples, and the spindle's
// turning summed sample to sample (degrees, either direction; a jump between sessions counts
// too, so the sum bounds the angle steps from above). Work bounds are estimated from it
// (force_model::expected_rows) before a log is predicted.
struct MotionExtent {
    std::size_t samples = 0;
    double spindle_turned_deg = 0;
    double last_angle_deg = 0;   // the last sample's angle, where the sum continues
    void add(double spindle_angle_deg) {
        if (samples > 0) spindle_turned_deg += std::abs(spindle_angle_deg - last_angle_deg);
        last_angle_deg = spindle_angle_deg;
        ++samples;
    }
};

struct IngestReport {
    std::string file;
    std::string format;                            // "csv" | "shdr"
    double duration_s = 0;
    std::size_t sessions = 0;
    std::size_t blocks = 0;
    std::map<std::string, ChannelReport> channels; // "pos", "feed", "spindle", "block", ...
    double feed_raw_min_mm_min = 0, feed_raw_max_mm_min = 0;         // plain differencing
    double feed_repaired_min_mm_min = 0, feed_repaired_max_mm_min = 0;
    // Machine position of the first repaired sample (where an NC program of the log starts).
    std::optional<std::array<double, 3>> first_position_mm;
    // What the log can carry (docs/formats.md, "Coarse data"): the step its positions are written
    // to (absent: too few moves to tell), the highest spindle speed read (absolute), and whether it
    // holds commanded positions besides the actual ones (Positions::Commanded reads them).
    std::optional<double> position_step_mm;
    double spindle_max_rpm = 0;
    bool commanded_positions = false;
    std::string rotary_axes;                       // the rotary axes the log holds: "", "c", "ac", ...
    MotionExtent extent;                           // of the repaired motion (inspect too)
    std::vector<IngestWarning> warnings;
};

// Can a log carry a force prediction for a tool with `teeth` edges? Positions written coarser than
// 0.01 mm (position_quantized, already among the report's warnings) make velocities, and so chip
// thickness and force, uncertain; a position period longer than a tooth period at the highest
// logged spindle speed (sampling_coarse) means the path within a tooth engagement is interpolated,
// not logged. The rule (docs/formats.md): a prediction is still made, with these warnings and
// `coarse` in its result; it is never made silently.
struct SamplingCheck {
    double sample_period_s = 0;              // median interval of the position readings
    std::optional<double> position_step_mm;
    double spindle_max_rpm = 0;
    double tooth_period_s = 0;               // at spindle_max_rpm; 0 without a spindle speed
    bool position_quantized = false, sampling_coarse = false;
    bool coarse() const { return position_quantized || sampling_coarse; }
    std::vector<IngestWarning> warnings;     // sampling_coarse (position_quantized is in the report)
};
SamplingCheck check_sampling(const IngestReport& report, int teeth);
// {coarse, sample_period_s, position_step_mm, spindle_max_rpm, tooth_period_s, position_quantized,
//  sampling_coarse, warnings[{code, count, message}]}
nlohmann::json to_json(const SamplingCheck& check);

// Names of the channel-map presets bundled with cutload (data/maps/*.json), for --map NAME.
std::vector<std::string> map_presets();

// The repaired motion: uniform time step inside each session. Sessions are concatenated; the
// first index of each is listed in session_start. Positions are machine positions as logged
// (setup offsets are applied by the force engine).
struct MotionModel {
    double step_s = 0.001;
    std::vector<double> t_s;
    std::vector<double> x_mm, y_mm, z_mm;
    std::vector<double> vx_mm_s, vy_mm_s, vz_mm_s;   // C0 estimates consistent with the C1 interpolant
    std::vector<double> spindle_rpm;                 // signed: positive = M03 (clockwise from spindle)
    std::vector<double> spindle_angle_deg;           // integrated from speed, unwrapped
    std::vector<std::int32_t> block;                 // index into block_names, -1 = unknown
    std::vector<std::string> block_names;
    // Tool number in the spindle per sample (-1: none or unknown); empty when nothing names tools
    // (a log without a tool channel, a model derived from one).
    std::vector<std::int32_t> tool;
    std::vector<std::size_t> session_start;          // always starts with 0 when non-empty
    // Rotary axes A, B, C (index 0, 1, 2) as logged, in degrees, unwrapped (a table displayed 0 to
    // 360 keeps counting past a turn), with their rates: each pair of vectors is empty when the log
    // has no such axis, else as long as t_s. Resampled per axis like the linear ones (joint space:
    // each servo interpolates its own axis). The engine does not read them: with a machine
    // definition, app::workpiece_motion turns them and x, y, z into the tool's motion against the
    // part (docs/five_axis.md, section 2.3).
    std::array<std::vector<double>, 3> rot_deg;
    std::array<std::vector<double>, 3> rot_vel_deg_s;

    std::size_t size() const { return t_s.size(); }
    bool has_rotary(int axis) const { return !rot_deg[std::size_t(axis)].empty(); }
};

// One interpolated state; position and velocity come from a cubic Hermite interpolant (C1).
struct MotionState {
    double t_s = 0;
    double pos_mm[3] = {0, 0, 0};
    double vel_mm_s[3] = {0, 0, 0};
    double spindle_rpm = 0;
    double spindle_angle_deg = 0;
    std::int32_t block = -1;
    std::int32_t tool = -1;   // tool in the spindle; -1: no tool channel
    double rot_deg[3] = {0, 0, 0};         // A, B, C; 0 where the model has no such axis
    double rot_vel_deg_s[3] = {0, 0, 0};
};

// The model's extent, as the ingest that built it reported it (IngestReport::extent).
MotionExtent motion_extent(const MotionModel& m);

// Interpolates the model at time t_s inside sample interval [i, i+1] (i + 1 < size()).
MotionState sample_between(const MotionModel& m, std::size_t i, double t_s);

// Whole pipeline into memory (predict, serve).
MotionModel ingest(const std::string& path, const ReadOptions& opt, IngestReport* report = nullptr);

// Streaming variants with bounded memory (inspect, resample of very long logs).
IngestReport inspect(const std::string& path, const ReadOptions& opt);
// The same, handing each sample of the repaired motion to `each_sample` as ingest would store it
// (positions, rotary axes, times bit for bit; a rotary axis the log lacks at 0) until it returns
// false: a caller can look at the motion as it passes without holding it.
IngestReport inspect(const std::string& path, const ReadOptions& opt, const std::function<bool(const MotionState&)>& each_sample);
// The same motion as ingest() builds, handed out in pieces of `piece_samples` samples (the last
// one shorter) as it is repaired, so that memory does not grow with the log's length (predict of
// an hour-long log). `piece` holds samples [first_sample, first_sample + piece.size()) of the
// whole model, bit for bit: its session_start lists, as indices into the piece, the sessions that
// begin in it (0 when the piece starts a session); block_names is the whole list so far (the
// names of every block its samples index); tool is -1 throughout for a log without a tool channel
// (where ingest() leaves it empty). The piece is reused: it is valid during the call only.
// `block_names`, when given, gets the log's whole list at the end.
IngestReport ingest_in_pieces(const std::string& path, const ReadOptions& opt, std::size_t piece_samples,
                              const std::function<void(const MotionModel& piece, std::size_t first_sample)>& each_piece,
                              std::vector<std::string>* block_names = nullptr);
// Writes t_s,x_mm,y_mm,z_mm,feed_mm_min,spindle_rpm,spindle_angle_deg,block; returns rows written.
std::size_t resample_to_csv(const std::string& path, const ReadOptions& opt, const std::string& out_csv,
                            IngestReport* report = nullptr);

// The report as one JSON object: file, format, duration_s, sessions, blocks,
// channels.<name>.{samples, interval_s.{min,median,max}, update_period_s, stale_dropped},
// feed_mm_min.{raw,repaired}.{min,max}, position_step_mm (null: unknown), spindle_max_rpm,
// commanded_positions, rotary_axes, warnings[{code, count, message}].
nlohmann::json report_to_json(const IngestReport& report);

}  // namespace cutload::motion_io
