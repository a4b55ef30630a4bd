// A log of machine axes turned into the tool's motion relative to the workpiece, through a machine
// definition (machine/, docs/machines.md): the first step of five-axis dry runs
// (docs/five_axis.md, section 2.3).
//
// At every sample of the repaired motion the axes (X, Y, Z from the log's linear channels, A, B,
// C from its rotary ones) go through forward kinematics, with the machine's geometric errors: the
// tool tip in workpiece coordinates becomes the sample's position, and its velocity the
// derivative of that tip along the axes' own rates (joint space: each servo interpolates its own
// axis), so a turning table feeds the tool with every linear axis still. The spindle angle is
// referred to the workpiece too: the cutter's angle relative to the part is the spindle's angle
// less the turn of the tool frame about its axis (so a C table turning at 30 deg/s under a spindle
// at 10 000 rpm shows 10 005 rpm against the part, or 9 995, by its sense). The engine then walks
// this motion as it walks a three-axis one.
//
// What the engine cannot take yet is refused, never approximated: a tool that turns away from the
// orientation it cuts at while it can reach the stock (that needs the multi-direction stock,
// docs/five_axis.md section 3); one fixed tilt is taken (tool_frame() below). The few microradians
// the machine's errors lean the tool are left out of the engagement; the tip's displacement by
// the errors is kept.
#pragma once

#include "force_model/force_model.hpp"
#include "machine/kinematics.hpp"
#include "machine/machine.hpp"
#include "motion_io/motion_io.hpp"
#include "motion_io/nc_program.hpp"

#include <array>
#include <cstddef>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

namespace cutload::app {

// A log that does not fit the machine, or a pose the engine cannot take; the message says what,
// and where (the axis and channel, or the time of the sample).
class WorkpieceMotionError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

// tool_frame()'s refusal of a tool that turns where it can reach the stock: simultaneous five-axis
// work, which predict_run takes on the multi-direction stock instead (turning_motion below).
class ToolTurnsInStock : public WorkpieceMotionError {
public:
    using WorkpieceMotionError::WorkpieceMotionError;
};

// The nominal tool axis may lean this far from the stock's +Z and still count as vertical
// (rounding of the kinematics, not a tilt).
inline constexpr double kVerticalToleranceRad = 1e-9;
// With the machine's geometric errors, it may lean this far (squareness and rotation errors are
// microradians; 1 mrad is a definition in the wrong units).
inline constexpr double kErrorTiltLimitRad = 1e-3;

// ---- Fixed tilt (docs/five_axis.md, "Fixed tilt: 3+2 machining") ----------------------------------
// A tool that leans from the stock's +Z is predicted when it keeps one orientation wherever it can
// reach the stock: indexed (3+2) work. The engine then runs in the tool's frame, where the tool is
// vertical and the stock a turned box (force_model::make_turned_stock). Between cuts the tool may
// turn (an index move, the home position at the log's start) where neither it, nor a tool at the
// cutting orientation at its tip, can reach the stock box.

// Turning by less than this counts as one orientation: 0.1 mm from the tip it moves the tool by
// 10 nm, and an encoder's 0.001 deg quantisation is 1.7e-5 rad.
inline constexpr double kFixedOrientationToleranceRad = 1e-4;
// The tool can reach the stock when the segment from its tip up its axis for the tool length
// (gauge point to tip: cutter, shank and holder) passes within the widest radius plus this of the
// stock box. Generous: a sample apart the tool moves a fraction of it at any feed.
inline constexpr double kReachMarginMm = 1.0;

struct ToolReach {
    force_model::StockBox stock_box;     // stock coordinates
    std::array<double, 3> offset_mm{};   // workpiece to stock (the run spec's setup.offset_mm)
    double radius_mm = 0;                // the widest of cutters and holders
    double length_mm = 0;                // the longest tip to holder top (stickout + holder length)
};

struct ToolFrame {
    bool checked = false;   // made by tool_frame(): the orientations were checked against the stock
    bool tilted = false;    // the tool leans where it cuts: the engine runs in its frame
    Eigen::Matrix3d tool_to_workpiece = Eigen::Matrix3d::Identity();   // the cutting orientation
    double lean_deg = 0;    // its axis from the stock's +Z
    double t_s = 0;         // the first sample where the tool can reach the stock (else the log's first)
    // The engine's frame: p_engine = grid_from_stock() p_stock (the transpose of tool_to_workpiece).
    force_model::Rotation3 grid_from_stock() const;
};

// An axis's lean from the stock's +Z; the angle of the rotation between two orientations; the
// orientation (tool to workpiece) a stock's grid frame holds (force_model::stock_grid_frame is
// its transpose, ToolFrame::grid_from_stock the way back).
double lean_from_z_rad(const Eigen::Vector3d& axis);
double orientation_angle_rad(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b);
Eigen::Matrix3d tool_to_workpiece(const force_model::Rotation3& grid_from_stock);

// The orientation the tool cuts at: its nominal pose at the first sample where it can reach the
// stock (a tool that never can is taken as vertical: nothing is cut). A tool standing vertical there may turn about its axis while it cuts (a C table under a
// vertical spindle); a tilted one must keep its whole orientation. Throws WorkpieceMotionError,
// naming the time and the angles, when the tool turns where it can reach the stock (simultaneous
// five-axis work needs the multi-direction stock, docs/five_axis.md section 3), and as
// workpiece_motion() does for a log the machine does not fit.
ToolFrame tool_frame(const motion_io::MotionModel& axes, const machine::Machine& machine, double tool_length_mm,
                     const ToolReach& reach);
// tool_frame's cutting orientation, found a sample at a time as a log is read (motion_io::inspect's
// visitor), so an upload knows it without holding the motion: the same poses (nominal forward
// kinematics) and the same rule, so the same frame, bit for bit. It does not check that the tool
// keeps that orientation where it can reach the stock (tool_frame does, on the ingested log). A
// sample costs one nominal forward call until the tool first can reach the stock, nothing after.
class CuttingOrientationWatch {
public:
    // Throws WorkpieceMotionError for a machine axis no log channel can give (as tool_frame does).
    CuttingOrientationWatch(const machine::Machine& machine, double tool_length_mm, const ToolReach& reach);
    // The next sample, in the log's order; false once the orientation is found (later samples
    // cannot change it).
    bool see(const machine::AxisPositions& q, double t_s);
    bool see(const motion_io::MotionState& s);
    bool found() const { return found_; }
    // As tool_frame() makes it (checked set), before its check of the other samples.
    ToolFrame frame() const;

private:
    const machine::Machine& machine_;
    double tool_length_mm_, reach_length_mm_;
    ToolReach reach_;
    std::vector<int> sources_;   // per chain axis: 0..2 the position x, y, z; 3..5 the rotary a, b, c
    bool seen_any_ = false, found_ = false;
    double first_t_s_ = 0, lean_rad_ = 0;
    Eigen::Matrix3d first_ = Eigen::Matrix3d::Identity();
};

// How far a nominal pose turns from the frame's cutting orientation where it matters: 0 within
// kFixedOrientationToleranceRad (a vertical frame: any turn about +Z), or where neither the pose nor
// the cutting orientation at its tip can reach the stock; else the angle (tool_frame's rule).
// `length_mm`: the tool's span from its tip.
double off_orientation_rad(const ToolFrame& frame, const machine::ToolPose& pose, double length_mm, const ToolReach& reach);

// Forces from the tool's frame into stock axes (torque, bending and engagement are the tool's
// own), and a motion model's positions and velocities turned by `rotation` (tool_to_stock turns
// the engine's frame into stock axes, its transpose back).
void turn_forces(std::span<force_model::ForceSample> rows, const Eigen::Matrix3d& tool_to_stock);
void turn_motion(motion_io::MotionModel& m, const Eigen::Matrix3d& rotation);

// `axes`: the repaired log in machine axes (motion_io::ingest). `tool_length_mm`: gauge point to
// tip along the spindle axis. Each rotary axis of the machine needs its channel in the log
// (Axis::channel, "a", "b" or "c"); a rotary channel the machine lacks is left out (the caller
// warns). Blocks, tools, sessions and spindle speeds carry over. With a frame from tool_frame()
// the orientations are taken as checked there, and for a tilted one the positions and velocities
// come in the tool's frame (grid_from_stock() applied; the run spec's offset must be turned the
// same way); without, any lean from the stock's +Z is refused.
motion_io::MotionModel workpiece_motion(const motion_io::MotionModel& axes, const machine::Machine& machine,
                                        double tool_length_mm, const ToolFrame& frame = {});

// A log whose tool turns where it can reach the stock (simultaneous five-axis work), as
// force_model::predict_turning takes it: the tip's motion in workpiece coordinates (positions
// from forward kinematics with the machine's errors, velocities along the axes' own rates, as
// workpiece_motion's), the spindle's own angle and speed (the engine turns the cutter against the
// tool frame, which the poses carry), and per sample the tool's orientation and the tool frame's
// angular velocity in its own axes: the body twist (machine::interval_twist) between the poses
// at the axes +-0.1 ms along their rates. Throws WorkpieceMotionError as workpiece_motion() does
// for a log the machine does not fit, and for errors that lean the tool more than
// kErrorTiltLimitRad off its nominal axis.
struct TurningMotion {
    motion_io::MotionModel motion;
    force_model::ToolPoses poses;
    double max_lean_deg = 0;   // the axis's largest lean from the stock's +Z over the log
};
TurningMotion turning_motion(const motion_io::MotionModel& axes, const machine::Machine& machine, double tool_length_mm);

// The engine's forces turned into the machine's (bed) axes: F_M = R_bed^T F_W, with R_bed the
// rotation of bed_to_workpiece (docs/five_axis.md, section 4), filled into each row's
// fx_machine_N, fy_machine_N, fz_machine_N; and the tool's axis in workpiece axes at the row's
// time (forward kinematics with the machine's errors) into tool_axis_x, tool_axis_y, tool_axis_z.
//
// Why here and not in the engine: the engine cuts in workpiece (stock) axes and must not know the
// machine (the layering keeps force_model off machine/); the application has both. Why at the
// row's own time rather than per motion sample: rows come every angle step, between the 1 ms
// samples, and a table turning 30 deg/s turns 0.03 deg in a sample; so each row's axes are taken
// from the axes' own Hermite at its time (motion_io::sample_between, as the engine takes the tip),
// and R_bed from the workpiece-side half of forward kinematics with the machine's errors: exact
// to the joint path. The tool axis comes from the same walk of the chain (machine::forward_with_bed),
// so a row costs one forward call: 0.47 us with the example errors against 0.71 to 0.75 us as
// forward and bed_to_workpiece apart (bench_kinematics, docs/five_axis.md section 0: 1.4 % of a
// core at 30 000 rows a second). The
// machine axes are kept for this, whole, until the prediction ends (about as much memory again as
// the motion model). Where R_bed is exactly the identity (every workpiece-side axis at 0 on a
// machine without errors) the forces are copied, so a machine at rest reports machine-axis forces
// identical to the workpiece ones, digit for digit.
class MachineAxesForces {
public:
    // `axes`: the repaired log in machine axes, as workpiece_motion() took it (the rows' times
    // are its times, its samples the engine's). Throws WorkpieceMotionError for an empty model or
    // one the machine does not fit (as workpiece_motion() does).
    MachineAxesForces(motion_io::MotionModel axes, std::shared_ptr<const machine::Machine> machine);
    // Which rows are which session's, as the engine says (force_model::PredictOptions::
    // session_begins): the rows from first_row on (counted over every apply() call) lie in samples
    // [begin, end). A row's time alone cannot say it: sessions may overlap in time (a restart
    // dump) and a session may end in a stretch without rows. Needed for a model of more than one
    // session; throws std::invalid_argument for a range that is not one of the model's sessions,
    // or a first_row before one already given.
    void begin_session(std::size_t begin, std::size_t end, std::size_t first_row);
    // Rows in the order the engine writes them (session by session, time-ordered within one),
    // continuing the count of those given before. Throws std::logic_error for rows of a model of
    // several sessions when begin_session() has not placed them.
    void apply(std::span<force_model::ForceSample> rows);

private:
    struct Place {
        std::size_t index;   // the sample at or before the row
        bool interval;       // the row lies in [index, index + 1] of its session (else: at sample index)
        double t_s;          // the row's time, inside the session
    };
    struct SessionRows {
        std::size_t first_row, begin, end;
    };
    Place locate(double t_s);

    motion_io::MotionModel axes_;
    std::shared_ptr<const machine::Machine> machine_;
    std::vector<int> source_;                 // per chain axis: 0..2 x, y, z; 3..5 the rotary a, b, c
    bool several_sessions_ = false;
    std::vector<SessionRows> starts_;         // from begin_session(), in row order
    std::size_t next_start_ = 0;              // the first of starts_ not yet entered
    std::size_t rows_seen_ = 0;               // rows given to apply() so far
    std::size_t begin_ = 0, end_ = 0;         // the current session's samples
    std::size_t index_ = 0;                   // cursor: the sample of the last row
};

// The machine's rotary axes as the NC reader takes them (NcReadOptions::rotary_axes): "AC".
std::string machine_rotary_axes(const machine::Machine& machine);

// Where the log's rotary axes start, by the machine's axis letters (A, B, C: what the NC reader's
// start_deg means), each read from the log channel the axis reads (machine::Axis::channel). 0 for
// a letter the machine lacks. Throws WorkpieceMotionError as turning_motion does for a log without
// an axis's channel.
std::array<double, 3> rotary_start_by_letter(const motion_io::MotionModel& log, const machine::Machine& machine);

// A machine-axis program's commanded motion (motion_io::commanded_motion: angles by axis letter,
// only the axes the program names) laid out as this machine's log holds it: each rotary axis in
// the channel it reads, and one the program never names held where the program starts it.
void program_axes_as_log(motion_io::MotionModel& axes, const motion_io::NcProgram& program,
                         const machine::Machine& machine);

// How closely the pieces of a joint-space block follow the tip's curved path (docs/five_axis.md
// section 2.4: 1 um), and the most pieces one block and the whole program become. A piece is a
// program block (272 B and 40 B a word: 0.4 to 0.5 kB), so the total bounds the memory a program
// can take here to about 0.5 GB: a full turn 100 mm from the C line takes 1024 pieces, a CAM
// program's degree-sized steps a few each. Counted as the pieces are made, so a hostile program
// is refused before it takes the memory.
inline constexpr double kProgramChordTolMm = 1e-3;
inline constexpr std::size_t kMaxPiecesPerBlock = std::size_t(1) << 16;
inline constexpr std::size_t kMaxProgramPieces = std::size_t(1) << 20;
struct PieceLimits {
    std::size_t per_block = kMaxPiecesPerBlock;
    std::size_t total = kMaxProgramPieces;   // blocks of the result, pieces or not
};

// A program read in the machine's axes (NcReadOptions::rotary_axes = machine_rotary_axes) as the
// tool tip's commanded path against the part, in workpiece coordinates like workpiece_motion's:
// every point goes through forward kinematics with the machine's errors. A straight block that
// turns no rotary axis stays one line (the linear axes move the tip rigidly); a block that turns
// one, and every arc, becomes straight pieces sharing its name and line (as a canned cycle's
// do), bisected until the tip's path lies within kProgramChordTolMm of them. Joint-space
// interpolation runs at a constant rate along the block, so each piece takes its share of the
// block's time (block_time_s at rapid_mm_min), and its feed_mm_min is the tip's speed against
// the part. The result has no rotary axes. Throws motion_io::NcProgramError naming the block as
// soon as a block or the program passes `limits` (saying how far into the block), and where the
// commanded tool axis is one the engine cannot cut with: with the log's checked frame (tool_frame)
// and the reach, a block that turns from the frame's orientation where the tool can reach the
// stock (the log's own rule: a fixed tilt is allowed, indexing in the air too); without them, any
// lean from the stock's +Z.
motion_io::NcProgram workpiece_program(const motion_io::NcProgram& program, const machine::Machine& machine,
                                       double tool_length_mm, double rapid_mm_min, const PieceLimits& limits = {},
                                       const ToolFrame& frame = {}, const std::optional<ToolReach>& reach = std::nullopt);

// As workpiece_program, for a log whose tool turns where it can reach the stock (simultaneous
// five-axis work, turning_motion): every orientation is taken, since the multi-direction stock
// cuts at any. The tip's path serves the block mapping and the comparison; the commanded run
// itself goes from the program's machine axes through turning_motion (predict_program's
// TurningCommand), so its poses are the chain's, not the pieces'.
motion_io::NcProgram turning_workpiece_program(const motion_io::NcProgram& program, const machine::Machine& machine,
                                               double tool_length_mm, double rapid_mm_min, const PieceLimits& limits = {});

}  // namespace cutload::app
