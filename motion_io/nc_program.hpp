// ISO 6983 NC programs in the common FANUC-style dialect: the programmed path of a 3-axis mill,
// block by block, in machine coordinates, plus the source text so the program can be written
// back with only its F words changed (see docs/nc_program.md).
//
// Supported: G00/G01/G02/G03 (arcs by I/J/K or R, helical; centres incremental or absolute,
// G90.1/G91.1), G04 dwell (X s, P ms), G17/G18/G19, G20/G21, G90/G91, G53, G54-G59, G94, canned
// drilling cycles (G73 G81 G82 G83 G85 G86 G89 with G98/G99, R, Q, P, G80, expanded into motion),
// F, S, M03/M04/M05, tools (T with M06), N numbers, (comments), ; comments, O numbers, %, block
// skip '/', no-op codes (G40, G43/G44/G49, G61/G64/G09, M00/M01/M07/M08/M09), M02/M30 end.
// With a machine's rotary axes (NcReadOptions::rotary_axes): A/B/C words in degrees in machine-axis
// form (every axis moves linearly between block end points), and G93 inverse time; with its
// kinematics too (NcReadOptions::tool_centre_point), tool-centre-point control G43.4/G43.5 until
// G49 (the tip in workpiece coordinates; NcBlock::tcp).
// Anything else is an NcProgramError naming file, line and word, unless the word is listed in
// NcReadOptions::ignore_words. Values outside physical ranges and programs whose path, duration
// or commanded-motion size pass NcLimits are refused while reading (issue 19).
#pragma once

#include "motion_io/motion_io.hpp"

#include <array>
#include <cstddef>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace cutload::motion_io {

// A bad program: "FILE:LINE: word 'G41': cutter compensation is not supported ...".
class NcProgramError : public IngestError {
public:
    using IngestError::IngestError;
};

enum class NcMotion { None, Rapid, Linear, ArcCw, ArcCcw, Dwell };

// Tool-centre-point control in force for a block: off, G43.4 (tip and rotary angles) or G43.5
// (tip and tool-axis vector I/J/K).
enum class ToolCentrePoint { Off, RotaryAngles, AxisVector };

// One word as written, with its place on the source line (for errors and for rewriting F).
struct NcWord {
    char letter = 0;          // upper case
    double value = 0;         // as written (program units)
    bool has_decimal_point = false;
    std::size_t column = 0;   // 0-based byte offset of the letter in the line
    std::size_t length = 0;   // bytes from the letter to the end of the number
};

// One block (one source line with words), or one motion of a canned cycle that a source line
// expands into (the pieces share the line, the name and the words). Positions are machine
// coordinates in mm, feeds mm/min.
struct NcBlock {
    std::string name;             // "N10", or "L<line>" for a block without a sequence number
    std::size_t line = 0;         // 1-based source line
    std::vector<NcWord> words;
    NcMotion motion = NcMotion::None;
    std::array<double, 3> start_mm{}, end_mm{};
    // Arcs: centre in machine coordinates, plane axes (G17: 0,1 normal 2; G18: 2,0 normal 1;
    // G19: 1,2 normal 0) and the signed sweep (positive counter-clockwise seen from +normal).
    std::array<double, 3> center_mm{};
    std::array<int, 3> plane_axes{0, 1, 2};
    double sweep_rad = 0;
    double feed_mm_min = 0;       // modal feed in force for this block (0 before any F)
    double spindle_rpm = 0;       // after this block's S/M words; signed: M03 > 0, M04 < 0
    double dwell_s = 0;
    bool has_feed_word = false;
    bool inch = false;            // G20 in force: F words of this block are in inch/min
    int tool = -1;                // tool number in the spindle for this block; -1 before the first change
    bool tool_change = false;     // this block changes the tool (M06, or T alone with tool_change_on_t)
    int cycle = 0;                // canned cycle this motion is part of (73, 81, 82, 83, 85, 86, 89); 0 none
    // Rotary axes A, B, C in machine degrees (0 where the program never names one; see
    // NcReadOptions::rotary_axes). A G00/G01 block whose angles change is a joint-space move: every
    // axis runs linearly from start to end, so the tip's path against the part is curved.
    std::array<double, 3> start_deg{}, end_deg{};
    // Seconds the block takes at its programmed feed when that is not the XYZ length over F: a
    // G93 block (1/F minutes), or a G01 that turns a rotary axis (by NcReadOptions::rotary_feed);
    // also a piece of a joint-space block turned into the tip's path (app::workpiece_program),
    // rapids included. 0 otherwise: the time is block_length_mm / feed_mm_min, as always.
    double feed_time_s = 0;
    bool inverse_time = false;    // G93 in force: the block's F word is 1/minutes, not a feed
    // Tool-centre-point blocks (G43.4/G43.5; docs/nc_program.md, "Tool-centre-point programs"):
    // the tip moves on a straight line in workpiece coordinates (the frame that turns with the
    // table) and the orientation is interpolated, so the machine axes run on a curve. start_mm /
    // end_mm and start_deg / end_deg hold the machine axes at the block's ends (from the machine's
    // kinematics, NcReadOptions::tool_centre_point), and feed_time_s the block's time at its
    // programmed feed; app::machine_axis_program turns the block into machine-axis pieces.
    ToolCentrePoint tcp = ToolCentrePoint::Off;
    std::array<double, 3> tip_start_mm{}, tip_end_mm{};   // the tool tip, workpiece coordinates
    std::array<double, 3> axis_start{}, axis_end{};       // the unit tool axis (tip toward spindle), workpiece coordinates
};

struct NcProgram {
    std::string file;
    std::vector<std::string> lines;   // source lines as read, without '\n' (a '\r' stays)
    bool final_newline = true;        // the source ended with '\n'
    std::vector<NcBlock> blocks;      // in program order; comment-only and empty lines are no blocks
    std::string rotary_axes;          // the rotary axes its words name, lower case in order: "", "c", "ac"
};

// Machine axes as a tool-centre-point program names them: X, Y, Z in mm and A, B, C in degrees
// (0 for an axis the machine lacks).
struct NcAxes {
    std::array<double, 3> linear_mm{};
    std::array<double, 3> rotary_deg{};
};

// The tool as a tool-centre-point program gives it, in workpiece coordinates.
struct NcToolPose {
    std::array<double, 3> tip_mm{};
    std::array<double, 3> axis{0, 0, 1};   // unit, from the tip toward the spindle
};

// A machine's kinematics on its nominal chain (what a controller in tool-centre-point mode uses).
// motion_io knows no machine definitions: the application implements this on machine/'s forward
// and inverse kinematics (app/tool_centre_point.hpp). The methods throw an exception derived from
// std::exception whose message names the axis and its limits when a target is out of reach.
class ToolCentrePointKinematics {
public:
    virtual ~ToolCentrePointKinematics() = default;
    virtual NcToolPose forward(const NcAxes& q) const = 0;
    // The axes that put the tool at `pose`, nearest `previous` within the limits (G43.5).
    virtual NcAxes inverse(const NcToolPose& pose, const NcAxes& previous) const = 0;
    // The linear axes that put the tip at tip_mm with the rotary axes at rotary_deg (G43.4).
    virtual NcAxes with_rotary(const std::array<double, 3>& tip_mm, const std::array<double, 3>& rotary_deg) const = 0;
};

enum class ArcCenters { Incremental, Absolute };   // I/J/K from the arc's start, or positions
enum class ProgramUnits { Mm, Inch };                // before any G20/G21

// How a G94 feed applies to a G01 that turns a rotary axis (controller-specific, so a setting and
// not a guess; docs/nc_program.md, "Rotary axes"):
// - Combined (FANUC): F over sqrt(dX^2 + dY^2 + dZ^2 + dA^2 + dB^2 + dC^2), degrees counted as
//   millimetres (as inches under G20);
// - LinearOnly: F over the X/Y/Z distance alone; a move with no X/Y/Z travel reads F as deg/min
//   over sqrt(dA^2 + dB^2 + dC^2).
enum class RotaryFeed { Combined, LinearOnly };

// Physical ranges of values and bounds on the work a program implies. A value outside its range
// is an error on its line and word; the work (programmed path, duration at programmed feeds and
// the rapid rate, and the commanded-motion samples at sample_step_s) is summed while reading and
// the block that passes a bound is an error too, so a typo cannot make later stages run away.
struct NcLimits {
    double max_abs_position_mm = 1e5;      // any coordinate, programmed or machine (100 m)
    double min_feed_mm_min = 0.1;          // F (0.004 in/min)
    double max_feed_mm_min = 200000;       // F; 200 m/min is beyond any machine's rapid traverse
    double min_rapid_mm_min = 100;         // the G00 rate (machine data)
    double max_rapid_mm_min = 200000;
    double max_dwell_s = 99999.999;        // G04 and cycle dwells (FANUC's own range)
    double max_spindle_rpm = 100000;       // S
    double max_path_mm = 1e7;              // 10 km of programmed path
    double max_duration_s = 86400;         // 24 h at programmed feed
    double max_samples = 1e7;              // commanded-motion samples (duration / sample_step_s)
    double sample_step_s = 0.001;          // the motion model's step the samples are counted at
};

struct NcReadOptions {
    // Machine position of each work coordinate system's zero for the tool tip ("G54" -> x, y, z).
    // Unset systems are an error when the program selects them; see default_work_offsets().
    std::map<std::string, std::array<double, 3>> work_offsets_mm;
    // Machine position before the first block (e.g. the log's first sample). Unset: each axis is
    // taken to sit where the program first puts it absolutely (an incremental move before that
    // is an error).
    std::optional<std::array<double, 3>> start_mm;
    // Words to drop before interpretation: a G/M code ("G28", "M98") or a single letter ("H").
    std::vector<std::string> ignore_words;
    // FANUC parameter 3401#0 (DPI) = 0: X10 without a decimal point means 10 least increments
    // (0.001 mm / 0.0001 in). Default false: calculator-style input, X10 = 10 mm.
    bool decimal_less_is_increment = false;
    // Arc centres (I/J/K) until the program says G90.1 or G91.1.
    ArcCenters arc_centers = ArcCenters::Incremental;
    // Length unit until the program says G20 or G21 (a post that leaves the unit to the control).
    ProgramUnits program_units = ProgramUnits::Mm;
    // An arc's end may lie off the circle through its start by arc_tolerance_mm + arc_tolerance_rel
    // x radius (a control's radius-error limit). The default accepts 3-decimal inch posts: start,
    // end and centre are each rounded by up to 0.0005 in per axis (0.018 mm), so an end sits up
    // to about 0.07 mm off the circle (typically 0.01 mm, 1 % of arcs beyond 0.037 mm).
    double arc_tolerance_mm = 0.075;
    double arc_tolerance_rel = 1e-4;
    // The control changes tools on T alone (no M06).
    bool tool_change_on_t = false;
    // The block skip switch is on: blocks starting with '/' are skipped (off: they run).
    bool block_skip = false;
    // Canned cycles: the G73 retract per peck (FANUC parameter 5114) and the G83 clearance above
    // the last peck's depth where the feed resumes (parameter 5115), mm.
    double peck_retract_mm = 0.5;
    double peck_clearance_mm = 0.5;
    // The machine's G00 rate, for the duration estimate.
    double rapid_mm_min = 30000;
    NcLimits limits;
    // The rotary axes of the machine the program runs on, upper case ("AC"; a machine definition's
    // rotary axes). Their words are read in machine-axis form, and G93 is accepted. Empty (no
    // machine, the default): an A/B/C word or G93 is an error naming the line and the word.
    std::string rotary_axes;
    RotaryFeed rotary_feed = RotaryFeed::Combined;
    // A, B, C before the first block (e.g. the log's first angles), degrees.
    std::array<double, 3> start_deg{};
    // The machine's kinematics, for G43.4/G43.5 (tool-centre-point control). Null: those codes
    // are an error naming the line and the word. Needs start_mm (the machine's position before
    // the program) and rotary_axes.
    std::shared_ptr<const ToolCentrePointKinematics> tool_centre_point;
};

// "combined" / "linear_only" (the CLI's and the API's spelling); nullopt for anything else.
std::optional<RotaryFeed> parse_rotary_feed(const std::string& text);
const char* rotary_feed_name(RotaryFeed f);

// Throws NcProgramError naming `what` when the rapid rate is outside the limits' range.
void check_rapid_feed(double rapid_mm_min, const NcLimits& limits, const std::string& what);

// The run spec's setup offset maps logged positions to stock coordinates (stock = machine +
// offset); a program written in stock coordinates therefore has its G54 zero at -offset.
std::map<std::string, std::array<double, 3>> default_work_offsets(const double setup_offset_mm[3]);

NcProgram parse_nc_program(const std::string& text, const std::string& file, const NcReadOptions& opt);
NcProgram read_nc_program(const std::string& path, const NcReadOptions& opt);   // NcProgramError on I/O too

// Path geometry of a block (0 for None/Dwell).
double block_length_mm(const NcBlock& b);
// Point and unit tangent at fraction u (0..1) of the block's path length.
void block_point(const NcBlock& b, double u, double pos_mm[3], double tangent[3]);
bool block_moves(const NcBlock& b);   // Rapid, Linear or an arc with non-zero length, or a rotary turn
bool block_turns(const NcBlock& b);   // a rotary axis changes in the block
// Seconds a moving block takes at its programmed feed, or at rapid_mm_min for G00 (a rapid that
// turns a rotary axis: the combined length, degrees as mm, at the rapid rate); 0 for the rest.
double block_time_s(const NcBlock& b, double rapid_mm_min);
// sqrt(dX^2 + dY^2 + dZ^2 + dA^2 + dB^2 + dC^2) of a line (mm, degrees counted as mm); arcs: their
// path length. The path parameter of a joint-space move.
double block_joint_length(const NcBlock& b);

// The tool numbers a program changes to, in the order it first uses them.
std::vector<int> program_tools(const NcProgram& program);

// The nearest feed at or below feed_mm_min that an F word of this block can state exactly
// (whole mm/min, or 0.1 in/min under G20).
double representable_feed_mm_min(const NcBlock& b, double feed_mm_min);

// The program text with the F words replaced so that every block with feed_mm_min[i] > 0 runs at
// that feed (program units, modal F tracked: an F word is inserted where the modal value would
// differ, replaced where one is written). Everything that is not an F word stays byte-identical.
std::string rewrite_feeds(const NcProgram& program, const std::vector<double>& feed_mm_min);

// The words of a line, as written (letter + number text), comments dropped: for comparing
// programs token by token.
std::vector<std::string> nc_tokens(const std::string& line);

}  // namespace cutload::motion_io
