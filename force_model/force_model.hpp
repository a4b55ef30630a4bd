// Public interface of force_model: the run specification (tool, material, stock, limits,
// resolution), the in-process stock, and the mechanistic force prediction over a motion model.
//
// Physics lives in plain value types and free functions; the heavy loops (engagement tests and
// stock removal) run either as OpenCL kernels (kernels/*.cl) or as their scalar C++ twins.
#pragma once

#include "motion_io/motion_io.hpp"

#include <nlohmann/json_fwd.hpp>

#include <array>
#include <atomic>
#include <cstdint>
#include <functional>
#include <iosfwd>
#include <memory>
#include <optional>
#include <stdexcept>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace cutload::force_model {

// A bad run spec: the message names the key (e.g. "tool.diameter_mm: must be > 0").
class SpecError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

// Flat, ball and bull-nose end mills; Drill: a sharp cone point (twist drill, spot drill);
// Chamfer: a cone from a flat tip (chamfer mill, spot drill with a flat); Barrel: a tip ball and a
// large flank arc (document 003's barrel tool, docs/run_spec.md).
enum class ToolShape { Flat, Ball, Bull, Drill, Chamfer, Barrel };

struct Holder {
    double diameter_mm = 0;
    double length_mm = 0;
};

struct ToolSpec {
    ToolShape shape = ToolShape::Flat;
    double diameter_mm = 8;
    int flutes = 2;
    double helix_deg = 30;
    double corner_radius_mm = 0;   // flat: 0; ball: diameter/2; bull: 0 < r < diameter/2; cones: 0
    double point_angle_deg = 0;    // drill, chamfer: the included angle of the cone
    double tip_diameter_mm = 0;    // chamfer: the flat at the tip (0: a sharp point)
    // flat, ball, bull: half angle of a tapered flank (0: cylindrical). diameter_mm is then the
    // diameter at the tip and the flank widens by tan(taper) per mm up to flute_length_mm.
    double taper_deg = 0;
    // barrel: radius r1 of the flank arc (> diameter_mm / 2) and r2 of the tip ball centred on the
    // axis (< diameter_mm / 2); diameter_mm is the barrel's widest, where the arc turns vertical.
    double barrel_radius_mm = 0;
    double tip_radius_mm = 0;
    double flute_length_mm = 20;
    double stickout_mm = 30;       // tip to holder face
    Holder holder;
};

// Step-over (pick feed) between parallel passes over a flat surface that leaves a cusp of
// cusp_height_mm under an arc of arc_radius_mm: 2 sqrt(h (2 rho - h)). A barrel tool's flank arc
// (barrel_radius_mm) gives a far larger step than a ball of the same diameter (document 003: r1 96 mm,
// 5 um: 1.960 mm; a 3 mm ball: 0.346 mm). Throws std::invalid_argument unless 0 < h <= rho.
double pick_feed_mm(double arc_radius_mm, double cusp_height_mm);

// Altintas' convention: dFt = Ktc h db + Kte db, dFr = Krc h db + Kre db, dFa = Kac h db + Kae db.
struct Material {
    std::string name;
    double Ktc_N_mm2 = 0, Krc_N_mm2 = 0, Kac_N_mm2 = 0;
    double Kte_N_mm = 0, Kre_N_mm = 0, Kae_N_mm = 0;
};

struct StockBox {
    double min_mm[3] = {0, 0, 0};
    double max_mm[3] = {0, 0, 0};
};

// A limit of 0 means "not checked".
struct Limits {
    double force_N = 0, torque_Nm = 0, power_kW = 0, chip_mm = 0, bending_MPa = 0;
    // A move at or above this path feed counts as a rapid: cutting during it trips rapid_in_material.
    // The log carries no G00/G01 mode, so the threshold is the only honest signal.
    double rapid_feed_mm_min = 20000;
    // Clearance shell around the holder (document 004's V_sh): stock nearer the holder than this,
    // without touching it, trips holder_near_miss with the block's smallest clearance. 0 (the
    // default): no near-miss check.
    double holder_clearance_mm = 0;
};

// A tool's own limits in a tool table: each one given replaces the run's for the rows that tool
// cuts; the others stay the run's. (The rapid feed is the machine's, not a tool's.)
struct LimitOverrides {
    std::optional<double> force_N, torque_Nm, power_kW, chip_mm, bending_MPa;
};
Limits limits_for(const Limits& run, const LimitOverrides& tool);

// One entry of the run spec's tool table: the tool a program calls by T number.
struct NumberedTool {
    int number = 0;
    ToolSpec tool;
    LimitOverrides limits;
};

struct Resolution {
    double angle_step_deg = 2;
    double axial_step_mm = 0.1;
    double grid_mm = 0.1;
};

struct RunSpec {
    // The run's one tool: it cuts every sample when there is no table, and the samples that name
    // no tool (no tool channel, before the first change) when there is one.
    ToolSpec tool;
    bool has_tool = true;               // false: the spec gives only a table
    std::vector<NumberedTool> tools;    // by T number; numbers unique
    Material material;
    StockBox stock;
    double offset_mm[3] = {0, 0, 0};   // added to logged positions -> tool tip in stock coordinates
    Limits limits;
    Resolution resolution;
};

RunSpec parse_run_spec(const nlohmann::json& j);     // throws SpecError naming the key
// The table entry with this T number, or null.
const NumberedTool* find_tool(const RunSpec& spec, int number);
// The most flutes of any tool the spec names (the tooth period a log's sampling must resolve).
int max_flutes(const RunSpec& spec);
RunSpec load_run_spec(const std::string& path);      // file errors are SpecError too
// A run spec's JSON text (an upload, a fuzzer's input); `source` starts every SpecError, and a
// text that is not JSON names line, column and key (textio/json.hpp).
RunSpec parse_run_spec_text(std::string_view text, const std::string& source);
nlohmann::json to_json(const RunSpec& spec);
// The run spec's JSON Schema as the parser reads it (every key, its type, whether required, a
// tool key's shapes, x-unit from the key's name, a title); published in the OpenAPI document.
nlohmann::json run_spec_schema();

// The in-process workpiece: a multi-interval Z-map (dexel) over the stock box. Opaque; it can be
// saved and loaded so a run can start from another run's final stock.
class Stock;
struct StockDeleter { void operator()(Stock*) const; };
using StockPtr = std::unique_ptr<Stock, StockDeleter>;
StockPtr make_stock(const StockBox& box, double grid_mm);
StockPtr copy_stock(const Stock& s);

// A rotation, as a row-major 3x3 matrix.
struct Rotation3 {
    std::array<double, 9> m{1, 0, 0, 0, 1, 0, 0, 0, 1};
    bool is_identity() const { return m == Rotation3{}.m; }
};
// The same box held for a tool tilted by a fixed rotation (docs/five_axis.md, "Fixed tilt"): the
// rays run along the tool's axis, on a grid in the tool's frame (p_grid = grid_from_stock p_stock)
// that covers the turned box; each ray holds the box's chord along it. The engine, walking the
// tool's motion in that frame (tip at grid_from_stock p_stock), cuts it as it cuts a three-axis
// stock. std::invalid_argument for a bad box or grid, or more than kMaxStockRays rays.
StockPtr make_turned_stock(const StockBox& box, const Rotation3& grid_from_stock, double grid_mm);
// The box make_turned_stock's grid covers, in grid coordinates (whole cells in x and y).
StockBox turned_stock_box(const StockBox& box, const Rotation3& grid_from_stock, double grid_mm);
// The rotation from stock coordinates into the stock's grid: the identity for make_stock's.
Rotation3 stock_grid_frame(const Stock& s);
// The box of a stock in stock coordinates (a turned stock's grid covers it turned).
StockBox stock_box(const Stock& s);
// One binary, versioned format, in memory (the service keeps stocks in its database) or in a file
// (written to PATH.tmp, then renamed). `source` names the bytes in errors, as a file's path does.
std::string save_stock_bytes(const Stock& s);
StockPtr load_stock_bytes(std::string_view bytes, const std::string& source);   // std::runtime_error when bad
void save_stock(const Stock& s, const std::string& path);
StockPtr load_stock(const std::string& path);                                  // std::runtime_error when bad
// The same format through any stream (a compressing one, say); errors start with `source`.
void save_stock(const Stock& s, std::ostream& out);
// How many bytes save_stock writes for `s` (a store can set their room aside first).
std::uint64_t stock_file_bytes(const Stock& s);
StockPtr load_stock(std::istream& in, const std::string& source);
double stock_volume_mm3(const Stock& s);

// The stock seen from above, for display (the web page's 3-D view): the top of the material over
// a grid of at most max_cells cells, each the highest top of the k x k rays it covers (so material
// is never shown removed where it remains). Row-major (j * nx + i), cell (i, j) spans
// x0 + i cell .. x0 + (i + 1) cell; NaN where no ray of the cell has material left. Holes and
// overhangs below the top are not represented. Always in stock coordinates: a turned stock's
// field takes, per cell, the highest upper end of a ray's material that falls in it.
struct StockHeightField {
    StockBox box;
    double x0_mm = 0, y0_mm = 0, cell_mm = 0;
    int nx = 0, ny = 0;
    int rays_per_cell = 1;        // k: the field's cell is k x k of the stock's rays
    std::vector<float> top_mm;
};
StockHeightField stock_height_field(const Stock& s, std::size_t max_cells);

enum class Device { OpenCL, Cpu };

// The OpenCL device predict() would use ("auto" choices in the CLI and service); throws
// std::runtime_error saying why when no OpenCL device is usable.
std::string opencl_device_name();
// Opens the process's OpenCL device and builds the engine's kernels into its pool, so that the
// first prediction starts at once; throws what opencl_device_name() throws.
void prepare_opencl();

// One row per angle step while cutting (air time coarser). Forces act on the tool.
struct ForceSample {
    double t_s = 0;
    double spindle_angle_deg = 0;
    std::int32_t block = -1;        // index into MotionModel::block_names
    std::int32_t tool = -1;         // T number of the tool in the spindle; -1: none named
    float fx_N = 0, fy_N = 0, fz_N = 0;
    float torque_Nm = 0, power_kW = 0;
    float chip_mm = 0;              // max uncut chip thickness over engaged elements
    float bending_MPa = 0;          // bending stress at the holder face
    float radial_engagement_mm = 0, axial_engagement_mm = 0;
    float removed_mm3 = 0;          // volume removed since the previous row
    bool holder_contact = false;
    // fx_N, fy_N, fz_N are in workpiece (stock) axes: the frame the engine cuts in. With a machine
    // definition the force also in the machine's (bed) axes, F_M = R_bed^T F_W (docs/five_axis.md,
    // section 4): filled by the application, which knows the machine (app::MachineAxesForces);
    // the engine leaves them 0. Written only with ForcesColumns::machine_axes.
    float fx_machine_N = 0, fy_machine_N = 0, fz_machine_N = 0;
    // The tool's axis at the row's time: a unit vector from the tip toward the spindle, in
    // workpiece (stock) axes. With a machine definition the application fills it from the
    // machine's pose at that time (it turns with the rotary axes, in the air too); the engine
    // leaves +Z, the axis of a three-axis cut. Written only with ForcesColumns::machine_axes.
    float tool_axis_x = 0, tool_axis_y = 0, tool_axis_z = 1;
};

struct FlagHit {
    std::string flag;      // force_limit, torque_limit, power_limit, chip_load_limit, bending_limit,
                           // rapid_in_material, holder_contact, holder_near_miss, spindle_stopped,
                           // unknown_tool
    double t_s = 0;        // first time it tripped
    double value = 0;      // the value that tripped it (units of the matching limit; unknown_tool:
                           // the T number, -1 for none; holder_near_miss: the block's smallest
                           // clearance in mm, and t_s its time)
    std::int32_t tool = -1;   // T number of the tool in the spindle when it tripped; -1: none named
};

struct BlockSummary {
    std::string block;
    // T number of the tool that cut in the block (the one with the most cutting rows), else of the
    // tool in the spindle at its end; -1: none named.
    std::int32_t tool = -1;
    double t_start_s = 0, t_end_s = 0;
    double peak_force_N = 0, mean_force_N = 0;
    double peak_torque_Nm = 0, peak_power_kW = 0;
    double max_chip_mm = 0, max_bending_MPa = 0;
    double max_radial_engagement_mm = 0, max_axial_engagement_mm = 0;
    double removed_mm3 = 0;
    std::vector<FlagHit> flags;
};

struct PredictStats {
    double simulated_s = 0;       // motion simulated: the sum of the sessions' spans
    double wall_s = 0;
    std::size_t steps = 0, cutting_steps = 0;
    std::string device;           // device name actually used
    // Samples whose tool the run spec's table does not have (no forces predicted for them; their
    // blocks are flagged unknown_tool), and those tools' T numbers (-1: samples naming no tool).
    std::size_t unknown_tool_samples = 0;
    std::vector<int> unknown_tools;
};

struct Prediction {
    std::vector<ForceSample> samples;
    std::vector<BlockSummary> blocks;
    std::vector<std::string> block_names;
    StockPtr final_stock;
    PredictStats stats;
};

// A stretch of a run's motion time (seconds, the log's own clock).
struct TimeWindow {
    double from_s = 0, to_s = 0;
};

// A clean point of a run's walk: the tool has just moved through air, every batch before it is
// complete and the whole path before it removed, so the stock there is all a walk resuming at it
// needs (PredictOptions::checkpoint and resume; docs/force_model.md, "Stock checkpoints").
struct StockCheckpoint {
    std::size_t sample = 0;   // the walk resumes with the interval that starts at this motion sample
    double t_s = 0;           // MotionModel::t_s[sample]: what a resume is checked against
};
// What a run's checkpoints belong to: a hash of everything the walk reads (the motion model's
// samples, blocks, tools and sessions, the run spec, the base stock's rays and walls) and of this
// build's checkpoint rules. A checkpoint is resumed only by a run of the same key.
std::uint64_t checkpoint_key(const motion_io::MotionModel& motion, const RunSpec& spec, const Stock* base_stock);
// The same key taken piece by piece, for a run whose motion is never held whole
// (motion_io::ingest_in_pieces): add() each piece in order, then key(). A model without a tool
// channel (tool empty) hashes as one whose samples name no tool (-1), as its pieces have it.
class CheckpointKey {
public:
    void add(const motion_io::MotionModel& piece, std::size_t first_sample);
    std::uint64_t key(double step_s, const RunSpec& spec, const Stock* base_stock) const;

private:
    // One hash per channel (t, x, y, z, vx, vy, vz, rpm, angle, block, tool, session starts).
    std::array<std::uint64_t, 12> hash_{};
    std::array<std::uint64_t, 12> count_{};
    bool started_ = false;
};

struct PredictOptions {
    Device device = Device::OpenCL;
    const Stock* base_stock = nullptr;                    // start from this stock instead of the box
    // Or start from this one, taken over rather than copied (a stock made for this run alone, such
    // as a turned stock); it comes back, cut, as Prediction::final_stock. Wins over base_stock.
    StockPtr* own_stock = nullptr;
    std::function<void(double fraction)> progress;        // 0..1, called from the calling thread
    const std::atomic<bool>* cancel = nullptr;            // set to stop early (throws Cancelled)
    // Most rows the prediction may hold (0: unchecked): checked as rows are written, so a run
    // whose estimate (expected_rows) was too low still stops (TooManyRows) instead of growing.
    std::size_t max_rows = 0;
    // When set, the rows are handed here as they become final (in time order within a session,
    // session after session: sessions may overlap in time), in pieces of about
    // kRowsOutPiece rows, and Prediction::samples comes back empty: memory then stays bounded by
    // the motion model and the stock, whatever the run's length (a run of an hour writes about 10^8
    // rows). Blocks, stats and the final stock are as without it, and so are the rows.
    std::function<void(std::span<const ForceSample> rows)> rows_out;
    // When set, called as the walk begins each session (MotionModel::session_start), before any of
    // its rows: the session's samples [begin, end) and the rows written before it (those handed to
    // rows_out included), so the rows from first_row up to the next call's are that session's.
    // Rows come session by session, but their times alone cannot say which session a row is of
    // where sessions overlap in time (a restart dump: a later session's times lie before the
    // previous one's), and a session may end in a stretch without rows (no angle step in its last
    // intervals).
    std::function<void(std::size_t begin, std::size_t end, std::size_t first_row)> session_begins;
    // False: the caller has no use for the final stock, so Prediction::final_stock comes back empty
    // and a GPU reads none of it back (the stock lives on the device for the run).
    bool keep_final_stock = true;
    // When set: only the rows with from_s <= t_s < to_s, the very rows the whole run computes
    // there (a zoom at full resolution on demand; docs/force_model.md, "A window on demand"). The
    // motion before the window is walked as the whole run walks it (batches, removal, its lag) for
    // its removal alone: no engagement is evaluated and no row kept before it. Blocks are
    // those the window covers, summarised over it; stats.simulated_s is the window's span and
    // stats.steps the steps evaluated (the window's, and the rest of the batches it starts and
    // ends in); no final stock comes back. A log of more than one session, a window
    // that is empty or outside the motion, and a turning run (predict_turning) are refused
    // (SpecError).
    std::optional<TimeWindow> window;
    // When set (and no window): called at the walk's clean points (StockCheckpoint), at least
    // checkpoint_every_s of motion apart and not before the first such span, with the stock as it
    // is there, current on the host (a GPU reads back the tiles cut since the last call). The stock
    // is only valid during the call. Not called for a log of more than one session.
    std::function<void(const StockCheckpoint& at, const Stock& stock)> checkpoint;
    double checkpoint_every_s = 60;
    // With a window: the walk starts at this checkpoint of a whole run of the same motion, spec and
    // tools, from its stock given as base_stock (or own_stock), instead of at the log's start. The
    // window's rows are the very rows the whole run computes there. Refused (SpecError): no window,
    // no stock, a checkpoint whose sample and time are not this motion's, or one after
    // window->from_s.
    std::optional<StockCheckpoint> resume;
};
// 8192 rows (0.7 MB): small enough that the pieces in flight (the engine's table, the pipe's
// copies) stay in cache and a short run's first prediction does not fault in 20 MB of fresh pages
// for them (cutload predict of a 10 s log: 0.44 to 0.40 s with 2^16 -> 2^13), large enough that
// handing a piece over costs nothing beside it.
inline constexpr std::size_t kRowsOutPiece = std::size_t(1) << 13;

class Cancelled : public std::runtime_error {
public:
    Cancelled() : std::runtime_error("prediction cancelled") {}
};

// A prediction stopped at PredictOptions::max_rows; the message gives the rows and the limit.
class TooManyRows : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

// The rows a prediction of a motion of this extent writes at most: one per angle step, plus one
// per motion sample (air, a stopped spindle, the step that closes an interval). An upper bound,
// so a run refused by it could not have fitted and one accepted cannot outgrow it.
std::size_t expected_rows(const motion_io::MotionExtent& extent, double angle_step_deg);

// Dexel cells (rays) of a stock over this box at this grid, as make_stock lays them out.
double stock_cells(const StockBox& box, double grid_mm);
// The most cells make_stock builds (it refuses more; run specs asking for more are refused too).
inline constexpr double kMaxStockRays = 4e8;
// Bytes one cell holds in memory: its rays' intervals and its sub-cell walls.
std::size_t stock_bytes_per_cell();

Prediction predict(const motion_io::MotionModel& motion, const RunSpec& spec, const PredictOptions& opt);

// For a process that runs prediction after prediction (the service, its workers, the benches that
// stand for them): the heap memory a finished prediction frees (its rows, its batches) stays with
// the process for the next one, instead of going back to the OS only for the next prediction to
// fault its pages in again. glibc otherwise trims the top of the heap when a large block at it is
// freed, depending on what else happens to lie above it: bench_force's device path with the stock
// in device buffers faulted 7 000 pages a prediction, about 9 ms of its 45 ms. Fixes the
// allocator's thresholds: blocks under 32 MiB from the heap, up to 32 MiB of free heap kept per
// arena (256 MiB kept cost the service 60 to 100 MB of resident memory on bench_long; 32 MiB
// leaves its peak where it was). Call once from the process's main, before its threads start
// (mallopt is not thread safe). False when the allocator refused (or is not glibc's): nothing
// changed then.
bool keep_freed_heap_for_next_prediction();

// ---- A tool that turns while it cuts (simultaneous five-axis work; docs/five_axis.md, 3.4) ------
// Per motion sample: the tool's orientation against the stock (row-major; its columns are the
// tool's x, y and z axes in stock coordinates, z from the tip toward the spindle) and the tool
// frame's angular velocity in its own axes (the body twist's omega, eqs. 3.16-3.22). The motion's
// positions and velocities are the tip's in workpiece coordinates (the run spec's offset turns them
// into stock coordinates, as for predict), and its spindle angle is the cutter's against the tool
// frame's x axis: the spindle's own.
struct ToolPoses {
    std::vector<Rotation3> tool_to_stock;
    std::vector<std::array<double, 3>> omega_tool_rad_s;
};
// Predicts such a motion on the multi-direction (tri-dexel) stock with the pose engine, on
// kernels/tri_dexel.cl when opt.device is OpenCL (on its twins, saying why in stats.device, when the
// device lacks double precision), else on the twins. Rows,
// block summaries, progress, cancel, max_rows, rows_out and session_begins as predict's; the final
// stock comes back as a Z-map of the box (the tri-dexel's Z family, ray for ray). SpecError for
// what it cannot take yet: several cutters, a base stock, a cutter whose cutting part is not
// convex.
Prediction predict_turning(const motion_io::MotionModel& motion, const ToolPoses& poses, const RunSpec& spec,
                           const PredictOptions& opt);
// The rays of the multi-direction stock of this box (its X, Y and Z families) and the bytes it
// holds while predict_turning runs (every ray written; plus the final Z-map it hands back).
double multi_direction_stock_rays(const StockBox& box, double grid_mm);
double multi_direction_stock_bytes(const StockBox& box, double grid_mm);

// Optional columns of FORCES.csv and FORCES.bin (docs/formats.md). Without any, the files are
// exactly as before these options existed.
struct ForcesColumns {
    // fx_machine_N, fy_machine_N, fz_machine_N and tool_axis_x, tool_axis_y, tool_axis_z after
    // the others (ForceSample::fx_machine_N ..., ForceSample::tool_axis_x ...): for a run with a
    // machine definition.
    bool machine_axes = false;
};

void write_forces_csv(const Prediction& p, const std::string& path);
// Where a prediction's rows go as they come (PredictOptions::rows_out), so the run's rows are never
// all held in memory: into a temporary file beside PATH (created exclusively), renamed to PATH by
// commit(). Destroyed without commit() (an error, a cancel) a writer removes its temporary file:
// a reader never sees a half-written file.
class ForcesWriter {
public:
    virtual ~ForcesWriter() = default;
    // The names the rows' block indices refer to (MotionModel::block_names), before their rows.
    virtual void set_block_names(const std::vector<std::string>& block_names) = 0;
    virtual void write(std::span<const ForceSample> rows) = 0;
    virtual void commit() = 0;
    virtual std::uint64_t bytes_written() const = 0;
};

// FORCES.csv (docs/formats.md): about 90 bytes a row. Throws std::runtime_error when it cannot
// write beside PATH.
std::unique_ptr<ForcesWriter> make_forces_csv_writer(const std::string& path, const ForcesColumns& columns = {});
// FORCES.bin (docs/formats.md, "FORCES.bin"): FORCES.csv's columns at FORCES.csv's resolution,
// column by column in chunks of kForcesBinChunkRows rows, each value the zigzag varint of its
// difference from the row before: about a fifth of the CSV's size, and exact to the CSV's digits.
// write() throws std::runtime_error for a value it cannot carry (not finite, or beyond 9e15
// quanta); set_block_names() after the first rows is a std::logic_error.
inline constexpr std::size_t kForcesBinChunkRows = std::size_t(1) << 16;
std::unique_ptr<ForcesWriter> make_forces_bin_writer(const std::string& path, const ForcesColumns& columns = {});
// FORCES.bin when the path ends in ".bin", else FORCES.csv.
std::unique_ptr<ForcesWriter> open_forces_writer(const std::string& path, const ForcesColumns& columns = {});
// All of a prediction's rows at once, in the format open_forces_writer picks.
void write_forces_file(const Prediction& p, const std::string& path, const ForcesColumns& columns = {});

// Columns appended to BLOCKS.csv: `header` starts with ',', fields(block) gives the block's
// fields, also starting with ','. (The NC program comparison adds its columns this way.)
struct BlockCsvExtra {
    std::string header;
    std::function<std::string(const BlockSummary&)> fields;
};
void write_blocks_csv(const Prediction& p, const std::string& path, const BlockCsvExtra& extra = {});

}  // namespace cutload::force_model
