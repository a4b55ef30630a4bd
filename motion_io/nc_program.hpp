// ISO 6983 NC programs in the common FANUC-style dialect: the programmed path of a 3-axis mill,
// block by block, in machine coordinates, plus the source text so the program can be written
// back with only its F words changed (see docs/nc_program.md).
//
// Supported: G00/G01/G02/G03 (arcs by I/J/K or R, helical), G04 dwell (X s, P ms), G17/G18/G19,
// G20/G21, G90/G91, G53, G54-G59, G94, F, S, M03/M04/M05, N numbers, (comments), ; comments, O
// numbers, %, no-op codes (G40, G43/G44/G49, G61/G64/G09, G80, M00/M01/M07/M08/M09), one tool
// (T, M06), M02/M30 end. Anything else is an NcProgramError naming file, line and word, unless
// the word is listed in NcReadOptions::ignore_words.
#pragma once

#include "motion_io/motion_io.hpp"

#include <array>
#include <cstddef>
#include <map>
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

// One word as written, with its place on the source line (for errors and for rewriting F).
struct NcWord {
    char letter = 0;          // upper case
    double value = 0;         // as written (program units)
    bool has_decimal_point = false;
    std::size_t column = 0;   // 0-based byte offset of the letter in the line
    std::size_t length = 0;   // bytes from the letter to the end of the number
};

// One block (one source line with words). Positions are machine coordinates in mm, feeds mm/min.
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
};

struct NcProgram {
    std::string file;
    std::vector<std::string> lines;   // source lines as read, without '\n' (a '\r' stays)
    bool final_newline = true;        // the source ended with '\n'
    std::vector<NcBlock> blocks;      // in program order; comment-only and empty lines are no blocks
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
};

// The run spec's setup offset maps logged positions to stock coordinates (stock = machine +
// offset); a program written in stock coordinates therefore has its G54 zero at -offset.
std::map<std::string, std::array<double, 3>> default_work_offsets(const double setup_offset_mm[3]);

NcProgram parse_nc_program(const std::string& text, const std::string& file, const NcReadOptions& opt);
NcProgram read_nc_program(const std::string& path, const NcReadOptions& opt);   // NcProgramError on I/O too

// Path geometry of a block (0 for None/Dwell).
double block_length_mm(const NcBlock& b);
// Point and unit tangent at fraction u (0..1) of the block's path length.
void block_point(const NcBlock& b, double u, double pos_mm[3], double tangent[3]);
bool block_moves(const NcBlock& b);   // Rapid, Linear or an arc with non-zero length

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
