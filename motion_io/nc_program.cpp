#include "motion_io/nc_program.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <fstream>
#include <iterator>
#include <numbers>
#include <sstream>

namespace cutload::motion_io {
namespace {

constexpr double kMmPerInch = 25.4;

// Bytes as an error message can show them: printable ASCII as is, anything else as \xNN, so a
// message stays valid UTF-8 (and JSON) whatever the program's encoding.
std::string printable(std::string_view s) {
    std::string out;
    for (const char ch : s) {
        const auto u = static_cast<unsigned char>(ch);
        if (u >= 0x20 && u < 0x7f) out += ch;
        else out += fmt::format("\\x{:02X}", static_cast<unsigned>(u));
    }
    return out;
}

struct LineWords {
    std::vector<NcWord> words;
    std::vector<std::string> texts;   // each word as written
    bool tape_mark = false;           // the line starts with '%'
    bool skip = false;                // the block starts with '/' (optional block skip)
    std::string error_word, error_what;
};

// Bytes that separate words: blanks, and a no-break space as Latin-1/cp1252 (A0) or UTF-8 (C2 A0)
// writes it (editors put them in). Returns how many bytes at i are such a separator.
std::size_t blank_at(const std::string& line, std::size_t i) {
    const auto u = static_cast<unsigned char>(line[i]);
    if (u == ' ' || u == '\t' || u == '\r') return 1;
    if (u == 0xA0) return 1;
    if (u == 0xC2 && i + 1 < line.size() && static_cast<unsigned char>(line[i + 1]) == 0xA0) return 2;
    return 0;
}

// Splits a line into words; comments "( ... )" and "; ..." are dropped whatever bytes they hold
// (an operator's note in cp1252 or UTF-8 is no error). On the first malformed character the error
// fields are set and scanning stops.
LineWords tokenize(const std::string& line) {
    LineWords out;
    std::size_t i = 0;
    const std::size_t n = line.size();
    auto fail = [&](std::string word, std::string what) {
        out.error_word = std::move(word);
        out.error_what = std::move(what);
    };
    // A UTF-8 byte order mark (the first line of a file saved by some editors).
    if (line.compare(0, 3, "\xEF\xBB\xBF") == 0) i = 3;
    while (i < n) {
        const char c = line[i];
        if (const std::size_t b = blank_at(line, i)) {
            i += b;
        } else if (c == '(') {
            const std::size_t close = line.find(')', i);
            if (close == std::string::npos) return fail(line.substr(i), "comment without ')'"), out;
            i = close + 1;
        } else if (c == ';') {
            break;
        } else if (c == '%' && out.words.empty()) {
            out.tape_mark = true;
            ++i;
        } else if (c == '/' && !out.skip &&
                   std::all_of(out.words.begin(), out.words.end(), [](const NcWord& w) { return w.letter == 'N'; })) {
            // "/" or "/1".."/9" at the head of a block (after its N number at most).
            out.skip = true;
            ++i;
            if (i < n && line[i] >= '1' && line[i] <= '9') ++i;
        } else if (std::isalpha(static_cast<unsigned char>(c)) || (c == ':' && out.words.empty())) {
            NcWord w;
            // ':' at the head of a block is ISO's program number address, as 'O'.
            w.letter = c == ':' ? 'O' : static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
            w.column = i;
            std::size_t j = i + 1;
            while (j < n && (line[j] == ' ' || line[j] == '\t')) ++j;   // FANUC allows "X 10."
            if (j < n && line[j] == '#') {
                std::size_t e = j + 1;
                while (e < n && std::isalnum(static_cast<unsigned char>(line[e]))) ++e;
                return fail(line.substr(i, e - i), "macro variables are not supported"), out;
            }
            const std::size_t num_start = j;
            if (j < n && (line[j] == '+' || line[j] == '-')) ++j;
            bool digits = false;
            while (j < n && (std::isdigit(static_cast<unsigned char>(line[j])) || line[j] == '.')) {
                if (line[j] == '.') {
                    if (w.has_decimal_point) break;
                    w.has_decimal_point = true;
                } else {
                    digits = true;
                }
                ++j;
            }
            if (!digits) return fail(line.substr(i, std::max<std::size_t>(j - i, 1)), "expected a number after the letter"), out;
            const std::string num = line.substr(num_start, j - num_start);
            try {
                w.value = std::stod(num);
            } catch (const std::exception&) {
                return fail(line.substr(i, j - i), "not a number"), out;
            }
            if (!std::isfinite(w.value)) return fail(line.substr(i, j - i), "not a finite number"), out;
            w.length = j - i;
            out.words.push_back(w);
            out.texts.push_back(line.substr(i, j - i));
            i = j;
        } else if (c == '#') {
            std::size_t e = i + 1;
            while (e < n && std::isalnum(static_cast<unsigned char>(line[e]))) ++e;
            return fail(line.substr(i, e - i), "macro variables are not supported"), out;
        } else if (static_cast<unsigned char>(c) >= 0x80) {
            return fail(std::string(1, c), "a byte outside a comment that is not part of an NC word"), out;
        } else {
            return fail(std::string(1, c), "unexpected character"), out;
        }
    }
    return out;
}

std::string word_text(const std::string& line, const NcWord& w) { return line.substr(w.column, w.length); }

bool is_code(const NcWord& w, char letter, double code) { return w.letter == letter && std::abs(w.value - code) < 1e-6; }

bool matches_ignore(const NcWord& w, const std::vector<std::pair<char, double>>& ignore) {
    for (const auto& [letter, code] : ignore)
        if (w.letter == letter && (std::isnan(code) || std::abs(w.value - code) < 1e-6)) return true;
    return false;
}

std::vector<std::pair<char, double>> parse_ignore(const std::vector<std::string>& words) {
    std::vector<std::pair<char, double>> out;
    for (const std::string& s : words) {
        if (s.empty() || !std::isalpha(static_cast<unsigned char>(s[0])))
            throw NcProgramError(fmt::format("ignore word '{}': expected a letter or a code like G28", printable(s)));
        const char letter = static_cast<char>(std::toupper(static_cast<unsigned char>(s[0])));
        if (s.size() == 1) {
            out.emplace_back(letter, std::nan(""));
            continue;
        }
        try {
            std::size_t used = 0;
            const double v = std::stod(s.substr(1), &used);
            if (used != s.size() - 1) throw std::invalid_argument(s);
            out.emplace_back(letter, v);
        } catch (const std::exception&) {
            throw NcProgramError(fmt::format("ignore word '{}': expected a letter or a code like G28", printable(s)));
        }
    }
    return out;
}

// Why a G code is refused; empty: supported.
std::string unsupported_g(double g) {
    const int code = static_cast<int>(std::lround(g * 10));
    switch (code) {
        case 410: case 420: return "cutter radius compensation is not supported (the path would be offset by the tool radius)";
        case 740: case 760: case 840: case 870: case 880:
            return "this canned cycle is not supported (supported: G73, G81, G82, G83, G85, G86, G89)";
        case 280: case 290: case 300: return "reference position return is not supported (the reference point is machine data; --ignore G28 drops it)";
        case 650: case 660: case 670: return "macro calls are not supported";
        case 950: return "feed per revolution (G95) is not supported; use G94";
        case 150: case 160: return "polar coordinates are not supported";
        case 680: case 690: return "coordinate rotation is not supported";
        case 500: case 510: return "scaling is not supported";
        case 100: case 110: return "programmable data input (G10) is not supported";
        case 520: case 920: return "local coordinate systems (G52/G92) are not supported";
        default: return "this G code is not supported";
    }
}

constexpr int kCycles[] = {73, 81, 82, 83, 85, 86, 89};

int cycle_code(const NcWord& w) {
    for (int c : kCycles)
        if (is_code(w, 'G', c)) return c;
    return 0;
}

// Parser state carried from block to block (modal values).
struct Modal {
    NcMotion motion = NcMotion::Rapid;   // FANUC parameter 3402#0 = 0: G00 at power-up
    int plane = 17;
    bool inch = false;
    bool incremental = false;
    bool absolute_centers = false;
    std::string wcs = "G54";
    double feed_mm_min = 0;
    double speed_rpm = 0;
    int direction = 0;                   // +1 M03, -1 M04, 0 stopped
    std::array<double, 3> pos_mm{};
    std::array<bool, 3> known{};
    int tool = -1;                       // in the spindle
    int next_tool = -1;                  // selected by T, waiting for M06
    // Canned cycle (group 09) and its modal hole data, as written (mm; R and Z absolute or
    // incremental as the block that uses them says).
    int cycle = 0;
    bool return_to_initial = true;       // G98 (power-up) or G99
    double initial_z_mm = 0;             // machine Z when the cycle mode was entered
    std::optional<double> r_mm, z_mm, q_mm;
    double dwell_s = 0;
    std::array<double, 3> rot_deg{};     // A, B, C (machine-axis form; read with a machine's rotary axes)
    bool inverse_time = false;           // G93 (else G94)
    // Tool-centre-point control (G43.4/G43.5 until G49): the programmed tip and tool axis in
    // workpiece coordinates. pos_mm and rot_deg stay the machine's axes throughout, so the block
    // after G49 starts where the machine is.
    ToolCentrePoint tcp = ToolCentrePoint::Off;
    std::array<double, 3> tip_mm{};
    std::array<double, 3> tool_axis{0, 0, 1};
};

const char* tcp_code(ToolCentrePoint t) { return t == ToolCentrePoint::AxisVector ? "G43.5" : "G43.4"; }

std::string vec_text(const std::array<double, 3>& v) { return fmt::format("({:.6g}, {:.6g}, {:.6g})", v[0], v[1], v[2]); }

// A rotary word beyond this is a typo, not a position (a continuous table logs turns, not years).
constexpr double kMaxAbsAngleDeg = 1e6;

class Parser {
public:
    Parser(const std::string& file, const NcReadOptions& opt) : file_(file), opt_(opt), lim_(opt.limits), ignore_(parse_ignore(opt.ignore_words)) {
        if (!(opt.arc_tolerance_mm >= 0) || !(opt.arc_tolerance_rel >= 0))
            throw NcProgramError(fmt::format("{}: the arc tolerance must be >= 0", file));
        if (!(opt.peck_retract_mm > 0) || !(opt.peck_clearance_mm > 0))
            throw NcProgramError(fmt::format("{}: the peck retract and clearance must be > 0", file));
        check_rapid_feed(opt.rapid_mm_min, lim_, file + ": rapid feed");
        if (!(lim_.sample_step_s > 0)) throw NcProgramError(fmt::format("{}: the sample step must be > 0", file));
        m_.inch = opt.program_units == ProgramUnits::Inch;
        m_.absolute_centers = opt.arc_centers == ArcCenters::Absolute;
        if (opt.start_mm) {
            m_.pos_mm = *opt.start_mm;
            m_.known = {true, true, true};
        }
        m_.rot_deg = opt.start_deg;
        for (const char c : opt.rotary_axes) {
            const char u = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
            if (u < 'A' || u > 'C') throw NcProgramError(fmt::format("{}: rotary axis '{}' is not A, B or C", file, printable(std::string(1, c))));
            rotary_allowed_[u - 'A'] = true;
        }
    }

    NcProgram parse(const std::string& text) {
        NcProgram p;
        p.file = file_;
        std::size_t start = 0;
        while (start < text.size()) {
            const std::size_t nl = text.find('\n', start);
            if (nl == std::string::npos) {
                p.lines.push_back(text.substr(start));
                p.final_newline = false;
                break;
            }
            p.lines.push_back(text.substr(start, nl - start));
            start = nl + 1;
        }
        for (std::size_t i = 0; i < p.lines.size() && !ended_; ++i) parse_line(p, i + 1, p.lines[i]);
        back_fill(p);
        for (int k = 0; k < 3; ++k)
            if (rotary_named_[k]) p.rotary_axes += static_cast<char>('a' + k);
        return p;
    }

private:
    [[noreturn]] void fail(std::size_t line, const std::string& word, const std::string& what) const {
        throw NcProgramError(fmt::format("{}:{}: word '{}': {}", file_, line, printable(word), what));
    }

    double length_mm(const NcWord& w) const {
        double v = w.value;
        if (opt_.decimal_less_is_increment && !w.has_decimal_point) v *= m_.inch ? 1e-4 : 1e-3;
        return m_.inch ? v * kMmPerInch : v;
    }

    // A length word within the physical range.
    double bounded_length_mm(std::size_t line_no, const std::string& line, const NcWord& w) const {
        const double v = length_mm(w);
        if (!(std::abs(v) <= lim_.max_abs_position_mm))
            fail(line_no, word_text(line, w), fmt::format("{:g} mm is outside the physical range +-{:g} mm", v, lim_.max_abs_position_mm));
        return v;
    }

    void check_position(std::size_t line_no, const std::string& word, const std::array<double, 3>& p) const {
        for (int a = 0; a < 3; ++a)
            if (!(std::abs(p[a]) <= lim_.max_abs_position_mm))
                fail(line_no, word, fmt::format("machine position {} {:g} mm is outside the physical range +-{:g} mm", "XYZ"[a], p[a],
                                                lim_.max_abs_position_mm));
    }

    double bounded_dwell_s(std::size_t line_no, const std::string& word, double s) const {
        if (!(s >= 0)) fail(line_no, word, "dwell time must be >= 0");
        if (!(s <= lim_.max_dwell_s)) fail(line_no, word, fmt::format("dwell {:g} s is above the longest, {:.10g} s", s, lim_.max_dwell_s));
        return s;
    }

    // Appends a block and adds its work (path, duration, commanded samples) to the running
    // totals; the block that passes a bound is the error, named by `culprit_`.
    void push(NcProgram& p, NcBlock b, std::size_t line_no) {
        known_at_block_.push_back(m_.known);
        if (b.motion == NcMotion::Dwell) {
            duration_s_ += b.dwell_s;
        } else if (block_moves(b)) {
            const double len = block_length_mm(b);
            path_mm_ += len;
            if (b.feed_time_s > 0 || block_turns(b)) duration_s_ += block_time_s(b, opt_.rapid_mm_min);
            else duration_s_ += len / ((b.motion == NcMotion::Rapid ? opt_.rapid_mm_min : b.feed_mm_min) / 60.0);
        }
        if (path_mm_ > lim_.max_path_mm)
            fail(line_no, culprit_, fmt::format("the programmed path reaches {:.4g} mm here, above the limit of {:.4g} mm", path_mm_, lim_.max_path_mm));
        if (duration_s_ > lim_.max_duration_s)
            fail(line_no, culprit_, fmt::format("the program runs {:.4g} s up to here at its feeds, above the limit of {:.4g} s", duration_s_,
                                                lim_.max_duration_s));
        if (duration_s_ / lim_.sample_step_s > lim_.max_samples)
            fail(line_no, culprit_, fmt::format("the commanded motion up to here takes {:.4g} samples at {:g} ms, above the limit of {:.4g}",
                                                duration_s_ / lim_.sample_step_s, lim_.sample_step_s * 1e3, lim_.max_samples));
        p.blocks.push_back(std::move(b));
    }

    void parse_line(NcProgram& p, std::size_t line_no, const std::string& line) {
        LineWords lw = tokenize(line);
        if (!lw.error_word.empty()) fail(line_no, lw.error_word, lw.error_what);
        // The second '%' ends the tape: whatever follows is not read.
        if (lw.tape_mark && seen_words_) {
            ended_ = true;
            return;
        }
        if (lw.words.empty()) return;
        seen_words_ = true;
        if (lw.skip && opt_.block_skip) return;
        std::vector<NcWord> words;
        for (const NcWord& w : lw.words)
            if (!matches_ignore(w, ignore_)) words.push_back(w);

        NcBlock b;
        b.line = line_no;
        b.words = lw.words;
        b.name = fmt::format("L{}", line_no);
        const NcWord* axis[3] = {nullptr, nullptr, nullptr};
        const NcWord* rot[3] = {nullptr, nullptr, nullptr};   // A, B, C
        const NcWord* center[3] = {nullptr, nullptr, nullptr};
        const NcWord *r_word = nullptr, *f_word = nullptr, *s_word = nullptr, *p_word = nullptr, *q_word = nullptr,
                     *t_word = nullptr, *motion_word = nullptr, *cycle_word = nullptr;
        bool dwell = false, machine_coords = false, m06 = false, cancel_cycle = false, cancel_tcp = false;
        int new_plane = 0, new_cycle = 0;
        const NcWord* tcp_word = nullptr;
        ToolCentrePoint new_tcp = ToolCentrePoint::Off;
        auto once = [&](const NcWord*& slot, const NcWord& w) {
            if (slot) fail(line_no, word_text(line, w), "appears twice in the block");
            slot = &w;
        };
        for (const NcWord& w : words) {
            const std::string text = word_text(line, w);
            switch (w.letter) {
                case 'N': b.name = fmt::format("N{}", static_cast<long long>(std::llround(w.value))); break;
                case 'O': break;   // program number
                case 'X': case 'Y': case 'Z': once(axis[w.letter - 'X'], w); break;
                case 'I': case 'J': case 'K': once(center[w.letter - 'I'], w); break;
                case 'R': once(r_word, w); break;
                case 'F': once(f_word, w); break;
                case 'S': once(s_word, w); break;
                case 'P': once(p_word, w); break;
                case 'Q': once(q_word, w); break;
                case 'H': break;   // tool length offset number: the tool length is part of the work offset
                case 'T':
                    once(t_word, w);
                    if (w.value < 0 || w.value > 99999999 || std::abs(w.value - std::round(w.value)) > 1e-9)
                        fail(line_no, text, "a tool number is a whole number from 0");
                    break;
                case 'G': {
                    const double g = w.value;
                    if (is_code(w, 'G', 0) || is_code(w, 'G', 1) || is_code(w, 'G', 2) || is_code(w, 'G', 3)) {
                        static constexpr NcMotion kinds[4] = {NcMotion::Rapid, NcMotion::Linear, NcMotion::ArcCw, NcMotion::ArcCcw};
                        m_.motion = kinds[static_cast<int>(std::lround(g))];
                        motion_word = &w;
                    } else if (const int cc = cycle_code(w)) {
                        if (cycle_word) fail(line_no, text, "two canned cycles in one block");
                        cycle_word = &w;
                        new_cycle = cc;
                    } else if (is_code(w, 'G', 80)) {
                        cancel_cycle = true;
                    } else if (is_code(w, 'G', 98) || is_code(w, 'G', 99)) {
                        m_.return_to_initial = is_code(w, 'G', 98);
                    } else if (is_code(w, 'G', 4)) {
                        dwell = true;
                    } else if (is_code(w, 'G', 17) || is_code(w, 'G', 18) || is_code(w, 'G', 19)) {
                        new_plane = static_cast<int>(std::lround(g));
                    } else if (is_code(w, 'G', 20) || is_code(w, 'G', 21)) {
                        m_.inch = is_code(w, 'G', 20);
                    } else if (is_code(w, 'G', 90) || is_code(w, 'G', 91)) {
                        m_.incremental = is_code(w, 'G', 91);
                    } else if (is_code(w, 'G', 90.1) || is_code(w, 'G', 91.1)) {
                        m_.absolute_centers = is_code(w, 'G', 90.1);
                    } else if (is_code(w, 'G', 53)) {
                        machine_coords = true;
                    } else if (g >= 54 - 1e-9 && g <= 59 + 1e-9 && std::abs(g - std::round(g)) < 1e-9) {
                        m_.wcs = fmt::format("G{}", static_cast<int>(std::lround(g)));
                        if (!opt_.work_offsets_mm.count(m_.wcs))
                            fail(line_no, text, "no offset is set for this work coordinate system (set its offset: --work-offset in the CLI, nc_options.work_offsets_mm in the API)");
                    } else if (is_code(w, 'G', 93)) {
                        // Inverse time only comes with rotary moves here: a three-axis program's F
                        // words stay feeds, which the feed optimizer rewrites.
                        if (!any_rotary_allowed())
                            fail(line_no, text, "inverse time feed (G93) is read only with a machine definition that has rotary axes (--machine FILE)");
                        m_.inverse_time = true;
                    } else if (is_code(w, 'G', 94)) {
                        m_.inverse_time = false;
                    } else if (is_code(w, 'G', 43.4) || is_code(w, 'G', 43.5)) {
                        if (tcp_word) fail(line_no, text, "two tool-centre-point codes in one block");
                        tcp_word = &w;
                        new_tcp = is_code(w, 'G', 43.4) ? ToolCentrePoint::RotaryAngles : ToolCentrePoint::AxisVector;
                    } else if (is_code(w, 'G', 43) || is_code(w, 'G', 44) || is_code(w, 'G', 49)) {
                        // Group 08: plain tool length compensation (a no-op here) ends tool-centre-point control too.
                        cancel_tcp = true;
                    } else if (is_code(w, 'G', 40) || is_code(w, 'G', 9) || is_code(w, 'G', 61) || is_code(w, 'G', 64)) {
                        // no effect on the programmed tool-tip path at programmed feed
                    } else {
                        fail(line_no, text, unsupported_g(g));
                    }
                    break;
                }
                case 'M': {
                    const int mc = static_cast<int>(std::lround(w.value));
                    if (std::abs(w.value - mc) > 1e-9) fail(line_no, text, "this M code is not supported");
                    if (mc == 3 || mc == 4) m_.direction = mc == 3 ? 1 : -1;
                    else if (mc == 5) m_.direction = 0;
                    else if (mc == 6) m06 = true;
                    else if (mc == 2 || mc == 30) ended_ = true;
                    else if (mc == 98 || mc == 99) fail(line_no, text, "subprograms are not supported");
                    else if (mc != 0 && mc != 1 && mc != 7 && mc != 8 && mc != 9)
                        fail(line_no, text, "this M code is not supported");
                    break;
                }
                case 'D': fail(line_no, text, "cutter compensation numbers (D) are not supported");
                case 'L': fail(line_no, text, "repeat counts (L) are not supported");
                case 'A': case 'B': case 'C': {
                    const int k = w.letter - 'A';
                    if (!any_rotary_allowed())
                        fail(line_no, text, fmt::format("rotary axis {} needs a machine definition with that axis (--machine FILE): without one "
                                                        "the program is read as three-axis, and a rotary move cannot be left out",
                                                        w.letter));
                    if (!rotary_allowed_[k])
                        fail(line_no, text, fmt::format("the machine has no rotary axis {} (its rotary axes: {})", w.letter,
                                                        allowed_rotary_names()));
                    once(rot[k], w);
                    rotary_named_[k] = true;
                    break;
                }
                case 'U': case 'V': case 'W':
                    fail(line_no, text, "only the linear axes X, Y and Z are supported");
                default: fail(line_no, text, "this address is not supported");
            }
        }
        if (new_plane) m_.plane = new_plane;
        if (tcp_word && cancel_tcp) fail(line_no, word_text(line, *tcp_word), "tool-centre-point control and its cancel (G43/G44/G49) in one block");
        if (cancel_tcp) m_.tcp = ToolCentrePoint::Off;
        if (tcp_word) enter_tcp(line_no, word_text(line, *tcp_word), new_tcp);
        std::optional<double> inverse_f_per_min;   // G93: this block's F, 1/min
        if (f_word && m_.inverse_time) {
            // The block takes 1/F minutes: from 0.6 ms (F100000) to a day (F1/1440).
            const double f = f_word->value;
            if (!(f >= 1.0 / 1440 && f <= 100000))
                fail(line_no, word_text(line, *f_word), "an inverse time feed (G93) must lie in 1/1440..100000 per minute (the block takes 1/F minutes)");
            inverse_f_per_min = f;
            b.has_feed_word = true;
            f_word = nullptr;   // not a feed: the G94 feed stays as it was
        }
        if (f_word) {
            const double f = m_.inch ? f_word->value * kMmPerInch : f_word->value;
            if (!(f > 0)) fail(line_no, word_text(line, *f_word), "feed must be > 0");
            if (f < lim_.min_feed_mm_min || f > lim_.max_feed_mm_min)
                fail(line_no, word_text(line, *f_word),
                     fmt::format("feed {:g} mm/min is outside the physical range {:g}..{:g} mm/min", f, lim_.min_feed_mm_min, lim_.max_feed_mm_min));
            m_.feed_mm_min = f;
            b.has_feed_word = true;
        }
        if (s_word) {
            if (s_word->value < 0) fail(line_no, word_text(line, *s_word), "spindle speed must be >= 0");
            if (s_word->value > lim_.max_spindle_rpm)
                fail(line_no, word_text(line, *s_word), fmt::format("spindle speed is above the physical range, {:g} rpm", lim_.max_spindle_rpm));
            m_.speed_rpm = s_word->value;
        }
        select_tool(b, line_no, t_word, m06);
        b.feed_mm_min = m_.feed_mm_min;
        b.spindle_rpm = m_.direction * m_.speed_rpm;
        b.inch = m_.inch;
        b.start_mm = b.end_mm = m_.pos_mm;
        b.start_deg = b.end_deg = m_.rot_deg;
        b.inverse_time = m_.inverse_time;
        culprit_ = word_text(line, words.empty() ? lw.words.front() : words.front());
        for (const NcWord* w : {axis[0], axis[1], axis[2]})
            if (w) {
                culprit_ = word_text(line, *w);
                break;
            }

        // Canned cycles (group 09): a group 01 code or G80 ends one; the hole data are modal.
        if (motion_word && cycle_word) fail(line_no, word_text(line, *cycle_word), "a canned cycle and G00-G03 in one block");
        if (cancel_cycle || motion_word) m_.cycle = 0;
        if (cycle_word) {
            if (cancel_cycle) fail(line_no, word_text(line, *cycle_word), "a canned cycle and G80 in one block");
            if (!m_.cycle) {
                if (!m_.known[2]) fail(line_no, word_text(line, *cycle_word), "canned cycle before the Z position is known (the initial level)");
                m_.initial_z_mm = m_.pos_mm[2];
                m_.r_mm.reset();
                m_.z_mm.reset();
                m_.q_mm.reset();
                m_.dwell_s = 0;
            }
            m_.cycle = new_cycle;
        }
        const NcWord* rot_word = rot[0] ? rot[0] : rot[1] ? rot[1] : rot[2];
        if (m_.cycle && m_.tcp != ToolCentrePoint::Off)
            fail(line_no, cycle_word ? word_text(line, *cycle_word) : fmt::format("G{}", m_.cycle),
                 fmt::format("a canned cycle under tool-centre-point control ({}): cancel it with G49 first", tcp_code(m_.tcp)));
        if (m_.cycle) {
            if (rot_word) fail(line_no, word_text(line, *rot_word), "a rotary word in a canned cycle block");
            canned_cycle(p, std::move(b), line_no, line, axis, center, r_word, p_word, q_word, dwell, machine_coords);
            return;
        }
        if (q_word) fail(line_no, word_text(line, *q_word), "Q is supported only in canned cycles (G73, G83)");

        if (dwell) {
            if (axis[1] || axis[2] || center[0] || center[1] || center[2] || r_word || rot_word)
                fail(line_no, "G04", "a dwell block takes only X (s) or P (ms)");
            if (axis[0] && p_word) fail(line_no, word_text(line, *p_word), "give the dwell as X (s) or P (ms), not both");
            if (axis[0]) b.dwell_s = bounded_dwell_s(line_no, word_text(line, *axis[0]),
                                                     axis[0]->value * (opt_.decimal_less_is_increment && !axis[0]->has_decimal_point ? 1e-3 : 1.0));
            else if (p_word) b.dwell_s = bounded_dwell_s(line_no, word_text(line, *p_word), p_word->value * 1e-3);
            else fail(line_no, "G04", "a dwell needs X (s) or P (ms)");
            b.motion = NcMotion::Dwell;
            culprit_ = "G04";
            push(p, std::move(b), line_no);
            return;
        }
        if (p_word) fail(line_no, word_text(line, *p_word), "P is supported only as a dwell time (G04, G82, G89)");
        if (m_.tcp != ToolCentrePoint::Off) {
            tcp_block(p, std::move(b), line_no, line, words, axis, rot, center, r_word, motion_word, machine_coords, inverse_f_per_min);
            return;
        }

        const bool has_axes = axis[0] || axis[1] || axis[2] || rot_word;
        const bool arc = !machine_coords && (m_.motion == NcMotion::ArcCw || m_.motion == NcMotion::ArcCcw);
        if (arc && rot_word)
            fail(line_no, word_text(line, *rot_word), "a rotary axis cannot move in an arc block (G02/G03): program the turn with G01");
        const bool has_center = center[0] || center[1] || center[2];
        if (!arc && (has_center || r_word)) {
            const NcWord& w = r_word ? *r_word : *(center[0] ? center[0] : center[1] ? center[1] : center[2]);
            fail(line_no, word_text(line, w), machine_coords ? "arc words in a G53 block" : "arc words need G02 or G03");
        }
        if (!has_axes && !(arc && has_center)) {
            if (motion_word && arc && r_word) fail(line_no, word_text(line, *r_word), "an R arc needs an end point");
            push(p, std::move(b), line_no);
            return;
        }
        if (machine_coords && m_.incremental) fail(line_no, "G53", "G53 takes absolute machine positions (G90)");

        const std::array<double, 3> target = axis_target(p, b, line_no, line, axis, machine_coords);
        // G53 moves at the rapid rate whatever group 01 says (and leaves it as it is).
        const NcMotion motion = machine_coords ? NcMotion::Rapid : m_.motion;
        if (motion != NcMotion::Rapid && m_.inverse_time) {
            if (!inverse_f_per_min)
                fail(line_no, word_text(line, words.front()), "in inverse time (G93) every feed move needs its own F (1/min: the block takes 1/F minutes)");
        } else if (motion != NcMotion::Rapid && !(m_.feed_mm_min > 0)) {
            fail(line_no, word_text(line, words.front()), "no feed rate (F) is in force for this move");
        }
        b.motion = motion;
        b.end_mm = target;
        b.end_deg = rotary_target(line_no, line, rot, machine_coords);
        if (arc) make_arc(b, line, line_no, center, r_word);
        if (motion != NcMotion::Rapid) {
            if (inverse_f_per_min) b.feed_time_s = 60.0 / *inverse_f_per_min;
            else if (block_turns(b)) b.feed_time_s = rotary_feed_time_s(b);
        }
        m_.pos_mm = target;
        m_.rot_deg = b.end_deg;
        push(p, std::move(b), line_no);
    }

    // G43.4/G43.5: the tip and tool axis start where the machine's axes put them.
    void enter_tcp(std::size_t line_no, const std::string& word, ToolCentrePoint mode) {
        if (!opt_.tool_centre_point)
            fail(line_no, word, fmt::format("tool-centre-point control ({}) needs the machine's kinematics to find its axes: give the "
                                            "machine definition and the tool length (--machine FILE --tool-length-mm L in the CLI, "
                                            "parts kinematics and tool_length_mm in the API)", tcp_code(mode)));
        if (!(m_.known[0] && m_.known[1] && m_.known[2]))
            fail(line_no, word, "tool-centre-point control before the machine's X, Y and Z positions are known (start with an absolute move)");
        if (m_.tcp == ToolCentrePoint::Off) {
            NcToolPose pose;
            try {
                pose = opt_.tool_centre_point->forward(NcAxes{m_.pos_mm, m_.rot_deg});
            } catch (const std::exception& e) {
                fail(line_no, word, fmt::format("the machine's pose at {} {}: {}", vec_text(m_.pos_mm), vec_text(m_.rot_deg), e.what()));
            }
            m_.tip_mm = pose.tip_mm;
            m_.tool_axis = pose.axis;
        }
        m_.tcp = mode;
    }

    // A block under tool-centre-point control: X/Y/Z are the tip in workpiece coordinates (with the
    // work offset, as a three-axis program's positions), A/B/C (G43.4) or I/J/K (G43.5) the
    // orientation at the block's end. The machine's axes at the end come from its kinematics.
    void tcp_block(NcProgram& p, NcBlock b, std::size_t line_no, const std::string& line, const std::vector<NcWord>& words,
                   const NcWord* const axis[3], const NcWord* const rot[3], const NcWord* const center[3], const NcWord* r_word,
                   const NcWord* motion_word, bool machine_coords, std::optional<double> inverse_f_per_min) {
        const ToolCentrePoint mode = m_.tcp;
        const std::string code = tcp_code(mode);
        b.tcp = mode;
        b.tip_start_mm = b.tip_end_mm = m_.tip_mm;
        b.axis_start = b.axis_end = m_.tool_axis;
        const NcWord* rot_word = rot[0] ? rot[0] : rot[1] ? rot[1] : rot[2];
        const NcWord* center_word = center[0] ? center[0] : center[1] ? center[1] : center[2];
        if (machine_coords) fail(line_no, "G53", fmt::format("G53 under tool-centre-point control ({}): cancel it with G49 first", code));
        if (r_word) fail(line_no, word_text(line, *r_word), fmt::format("R under tool-centre-point control ({})", code));
        if (mode == ToolCentrePoint::RotaryAngles && center_word)
            fail(line_no, word_text(line, *center_word), "I/J/K under G43.4: the rotary words give the orientation (G43.5 takes the tool axis as I/J/K)");
        if (mode == ToolCentrePoint::AxisVector && rot_word)
            fail(line_no, word_text(line, *rot_word), "a rotary word under G43.5: give the tool axis as I/J/K (G43.4 takes rotary angles)");
        const bool has_axes = axis[0] || axis[1] || axis[2] || rot_word || center_word;
        if (!has_axes) {
            push(p, std::move(b), line_no);
            return;
        }
        if (m_.motion == NcMotion::ArcCw || m_.motion == NcMotion::ArcCcw)
            fail(line_no, motion_word ? word_text(line, *motion_word) : (m_.motion == NcMotion::ArcCw ? "G02" : "G03"),
                 fmt::format("circular interpolation under tool-centre-point control ({}) is not supported: program the tip path with G01", code));
        const auto wcs = opt_.work_offsets_mm.find(m_.wcs);
        if (wcs == opt_.work_offsets_mm.end()) fail(line_no, m_.wcs, "no offset is set for this work coordinate system");
        std::array<double, 3> tip = m_.tip_mm;
        for (std::size_t a = 0; a < 3; ++a) {
            if (!axis[a]) continue;
            const double v = bounded_length_mm(line_no, line, *axis[a]);
            tip[a] = m_.incremental ? m_.tip_mm[a] + v : v + wcs->second[a];
        }
        check_position(line_no, culprit_, tip);
        std::array<double, 3> tool_axis = m_.tool_axis;
        std::array<double, 3> rot_end = m_.rot_deg;
        if (mode == ToolCentrePoint::RotaryAngles) {
            rot_end = rotary_target(line_no, line, rot, false);
        } else if (center_word) {
            // Omitted components are 0; the vector is a direction, always absolute.
            const double v[3] = {center[0] ? center[0]->value : 0.0, center[1] ? center[1]->value : 0.0, center[2] ? center[2]->value : 0.0};
            const double n = std::hypot(v[0], v[1], v[2]);
            if (!(n > 1e-9)) fail(line_no, word_text(line, *center_word), "the tool axis I/J/K has no direction (all components 0)");
            tool_axis = {v[0] / n, v[1] / n, v[2] / n};
            const double dot = tool_axis[0] * m_.tool_axis[0] + tool_axis[1] * m_.tool_axis[1] + tool_axis[2] * m_.tool_axis[2];
            if (dot < -1 + 1e-12)
                fail(line_no, word_text(line, *center_word),
                     fmt::format("the tool axis turns from {} to its opposite {}: no great circle between the two is defined (split the turn "
                                 "into two blocks)", vec_text(m_.tool_axis), vec_text(tool_axis)));
        }
        const NcMotion motion = m_.motion;
        if (motion != NcMotion::Rapid && m_.inverse_time) {
            if (!inverse_f_per_min)
                fail(line_no, word_text(line, words.front()), "in inverse time (G93) every feed move needs its own F (1/min: the block takes 1/F minutes)");
        } else if (motion != NcMotion::Rapid && !(m_.feed_mm_min > 0)) {
            fail(line_no, word_text(line, words.front()), "no feed rate (F) is in force for this move");
        }
        NcAxes q;
        try {
            if (mode == ToolCentrePoint::RotaryAngles) {
                q = opt_.tool_centre_point->with_rotary(tip, rot_end);
                q.rotary_deg = rot_end;   // as commanded, digit for digit
                tool_axis = opt_.tool_centre_point->forward(q).axis;
            } else {
                q = opt_.tool_centre_point->inverse(NcToolPose{tip, tool_axis}, NcAxes{m_.pos_mm, m_.rot_deg});
            }
        } catch (const std::exception& e) {
            fail(line_no, culprit_, fmt::format("block {}: the machine cannot reach the tip {} {}: {}", b.name, vec_text(tip),
                                                mode == ToolCentrePoint::RotaryAngles ? "at the rotary angles " + vec_text(rot_end)
                                                                                      : "with the tool axis " + vec_text(tool_axis),
                                                e.what()));
        }
        b.motion = motion;
        b.end_mm = q.linear_mm;
        b.end_deg = q.rotary_deg;
        b.tip_end_mm = tip;
        b.axis_end = tool_axis;
        check_position(line_no, culprit_, b.end_mm);
        // The tip runs at F (G94) along its straight path; a block that only turns the tool reads
        // F as deg/min over the turn (G43.4: the rotary angles' combined turn, G43.5: the angle
        // between the axes). G93: 1/F minutes, as always.
        const double tip_mm = std::hypot(tip[0] - b.tip_start_mm[0], tip[1] - b.tip_start_mm[1], tip[2] - b.tip_start_mm[2]);
        double turn_deg = 0;
        if (mode == ToolCentrePoint::RotaryAngles) {
            turn_deg = std::hypot(rot_end[0] - b.start_deg[0], rot_end[1] - b.start_deg[1], rot_end[2] - b.start_deg[2]);
        } else {
            const double dot = b.axis_start[0] * tool_axis[0] + b.axis_start[1] * tool_axis[1] + b.axis_start[2] * tool_axis[2];
            turn_deg = std::acos(std::clamp(dot, -1.0, 1.0)) * 180.0 / std::numbers::pi;
        }
        if (motion == NcMotion::Rapid) {
            b.feed_time_s = std::hypot(tip_mm, turn_deg) / (opt_.rapid_mm_min / 60.0);
        } else if (inverse_f_per_min) {
            b.feed_time_s = 60.0 / *inverse_f_per_min;
        } else {
            const double unit_mm = b.inch ? kMmPerInch : 1.0;
            b.feed_time_s = tip_mm > 1e-9 ? tip_mm / (b.feed_mm_min / 60.0) : turn_deg / (b.feed_mm_min / unit_mm / 60.0);
        }
        for (int k = 0; k < 3; ++k)
            if (rotary_allowed_[k]) rotary_named_[k] = true;
        m_.pos_mm = b.end_mm;
        m_.rot_deg = b.end_deg;
        m_.tip_mm = tip;
        m_.tool_axis = tool_axis;
        push(p, std::move(b), line_no);
    }

    bool any_rotary_allowed() const { return rotary_allowed_[0] || rotary_allowed_[1] || rotary_allowed_[2]; }
    std::string allowed_rotary_names() const {
        std::string out;
        for (int k = 0; k < 3; ++k)
            if (rotary_allowed_[k]) out += static_cast<char>('A' + k);
        return out;
    }

    // The block's A/B/C words as machine angles: absolute (no work offset turns them), incremental
    // from where the axis is, or G53. Decimal-less words follow X/Y/Z's rule (0.001 deg increments).
    std::array<double, 3> rotary_target(std::size_t line_no, const std::string& line, const NcWord* const rot[3], bool machine_coords) const {
        std::array<double, 3> target = m_.rot_deg;
        for (int k = 0; k < 3; ++k) {
            if (!rot[k]) continue;
            double v = rot[k]->value;
            if (opt_.decimal_less_is_increment && !rot[k]->has_decimal_point) v *= 1e-3;
            target[k] = m_.incremental && !machine_coords ? m_.rot_deg[k] + v : v;
            if (!(std::abs(target[k]) <= kMaxAbsAngleDeg))
                fail(line_no, word_text(line, *rot[k]), fmt::format("{:g} deg is outside the physical range +-{:g} deg", target[k], kMaxAbsAngleDeg));
        }
        return target;
    }

    // Seconds a G94 G01 that turns a rotary axis takes at its feed, by opt_.rotary_feed. Under G20
    // the feed and the X/Y/Z travel are in inches, and Combined counts degrees as inches.
    double rotary_feed_time_s(const NcBlock& b) const {
        const double unit_mm = b.inch ? kMmPerInch : 1.0;
        const double linear = block_length_mm(b) / unit_mm, feed = b.feed_mm_min / unit_mm;
        const double turn = std::hypot(b.end_deg[0] - b.start_deg[0], b.end_deg[1] - b.start_deg[1], b.end_deg[2] - b.start_deg[2]);
        double length = std::hypot(linear, turn);
        if (opt_.rotary_feed == RotaryFeed::LinearOnly) length = linear > 1e-9 ? linear : turn;
        return length / feed * 60.0;
    }

    // T selects (and with tool_change_on_t changes); M06 changes to the selected tool.
    void select_tool(NcBlock& b, std::size_t line_no, const NcWord* t_word, bool m06) {
        auto change_to = [&](int tool) {
            b.tool_change = tool != m_.tool;
            m_.tool = tool;
        };
        if (t_word) {
            m_.next_tool = static_cast<int>(std::lround(t_word->value));
            if (opt_.tool_change_on_t) change_to(m_.next_tool);
        }
        if (m06 && !opt_.tool_change_on_t) {
            if (m_.next_tool < 0) fail(line_no, "M06", "tool change without a tool selected (no T word before it or in its block)");
            change_to(m_.next_tool);
        }
        b.tool = m_.tool;
    }

    // The block's X/Y/Z words as a machine position (absolute in the work system, incremental,
    // or G53 machine coordinates). An axis first given here is where it sat before.
    std::array<double, 3> axis_target(const NcProgram& p, NcBlock& b, std::size_t line_no, const std::string& line,
                                      const NcWord* const axis[3], bool machine_coords) {
        const auto wcs = opt_.work_offsets_mm.find(m_.wcs);
        if (wcs == opt_.work_offsets_mm.end())
            fail(line_no, m_.wcs, "no offset is set for this work coordinate system, active since the program start (set its offset: --work-offset in the CLI, nc_options.work_offsets_mm in the API)");
        const auto& offset = wcs->second;
        std::array<double, 3> target = m_.pos_mm;
        for (int a = 0; a < 3; ++a) {
            if (!axis[a]) continue;
            const double v = bounded_length_mm(line_no, line, *axis[a]);
            if (machine_coords) {
                target[a] = v;
            } else if (m_.incremental) {
                if (!m_.known[a])
                    fail(line_no, word_text(line, *axis[a]), "incremental move before the axis position is known (start with an absolute move)");
                target[a] = m_.pos_mm[a] + v;
            } else {
                target[a] = v + offset[a];
            }
            if (!m_.known[a]) {
                // The axis sat where it is first put: the block starts there.
                m_.pos_mm[a] = m_first_mm_[a] = target[a];
                m_.known[a] = true;
                became_known_at_[a] = p.blocks.size();
                b.start_mm[a] = target[a];
            }
        }
        check_position(line_no, culprit_, target);
        return target;
    }

    // One block in canned-cycle mode: updates the modal hole data and, when the block has an
    // X/Y/Z word, drills one hole at its X/Y (motion documented in docs/nc_program.md).
    void canned_cycle(NcProgram& p, NcBlock b, std::size_t line_no, const std::string& line, const NcWord* const axis[3],
                      const NcWord* const center[3], const NcWord* r_word, const NcWord* p_word, const NcWord* q_word, bool dwell,
                      bool machine_coords) {
        const std::string code = fmt::format("G{}", m_.cycle);
        if (dwell) fail(line_no, "G04", "a dwell in a canned cycle block");
        if (machine_coords) fail(line_no, "G53", "G53 in a canned cycle");
        if (center[2]) fail(line_no, word_text(line, *center[2]), "repeat counts (K) of canned cycles are not supported");
        if (center[0] || center[1]) fail(line_no, word_text(line, *(center[0] ? center[0] : center[1])), "arc words in a canned cycle");
        if (m_.plane != 17) fail(line_no, code, "canned cycles are supported in the G17 plane only (drilling along Z)");
        if (r_word) m_.r_mm = bounded_length_mm(line_no, line, *r_word);
        if (axis[2]) m_.z_mm = bounded_length_mm(line_no, line, *axis[2]);
        if (q_word) {
            const double q = bounded_length_mm(line_no, line, *q_word);
            if (!(q > 0)) fail(line_no, word_text(line, *q_word), "the peck depth Q must be > 0");
            m_.q_mm = q;
        }
        if (p_word) m_.dwell_s = bounded_dwell_s(line_no, word_text(line, *p_word), p_word->value * 1e-3);
        if (!(axis[0] || axis[1] || axis[2])) {
            push(p, std::move(b), line_no);   // hole data or other words only: no hole
            return;
        }
        if (!m_.z_mm) fail(line_no, code, "the canned cycle has no hole bottom (Z)");
        if (!m_.r_mm) fail(line_no, code, "the canned cycle has no R level (R)");
        if ((m_.cycle == 73 || m_.cycle == 83) && !m_.q_mm) fail(line_no, code, "a peck cycle needs the peck depth Q");
        if (!(m_.feed_mm_min > 0)) fail(line_no, code, "no feed rate (F) is in force for the canned cycle");
        const NcWord* xy[3] = {axis[0], axis[1], nullptr};
        std::array<double, 3> hole = axis_target(p, b, line_no, line, xy, false);
        if (!m_.known[0] || !m_.known[1]) fail(line_no, code, "canned cycle before the X and Y positions are known");
        // G90: R and Z are levels in the work system; G91: R is the distance from the initial
        // level, Z the distance from the R level (FANUC).
        const double offset_z = opt_.work_offsets_mm.at(m_.wcs)[2];
        const double r_level = m_.incremental ? m_.initial_z_mm + *m_.r_mm : *m_.r_mm + offset_z;
        const double bottom = m_.incremental ? r_level + *m_.z_mm : *m_.z_mm + offset_z;
        check_position(line_no, code, {hole[0], hole[1], r_level});
        check_position(line_no, code, {hole[0], hole[1], bottom});
        if (!(bottom < r_level)) fail(line_no, culprit_, fmt::format("the hole bottom Z lies at or above the R level ({:g} >= {:g} mm)", bottom, r_level));
        const double back = m_.return_to_initial ? std::max(m_.initial_z_mm, r_level) : r_level;

        b.cycle = m_.cycle;
        b.has_feed_word = false;
        bool emitted = false;
        auto move = [&](NcMotion kind, double z, bool spindle_stopped = false) {
            NcBlock s = b;
            s.motion = kind;
            s.start_mm = m_.pos_mm;
            s.end_mm = {hole[0], hole[1], z};
            if (spindle_stopped) s.spindle_rpm = 0;
            if (std::hypot(s.end_mm[0] - s.start_mm[0], s.end_mm[1] - s.start_mm[1], s.end_mm[2] - s.start_mm[2]) < 1e-9) return;
            m_.pos_mm = s.end_mm;
            emitted = true;
            push(p, std::move(s), line_no);
        };
        auto pause = [&](double seconds) {
            if (!(seconds > 0)) return;
            NcBlock s = b;
            s.motion = NcMotion::Dwell;
            s.start_mm = s.end_mm = m_.pos_mm;
            s.dwell_s = seconds;
            emitted = true;
            push(p, std::move(s), line_no);
        };
        // Positioning in X/Y at the current level, then rapid to R.
        {
            NcBlock s = b;
            s.motion = NcMotion::Rapid;
            s.start_mm = m_.pos_mm;
            s.end_mm = {hole[0], hole[1], m_.pos_mm[2]};
            if (std::hypot(s.end_mm[0] - s.start_mm[0], s.end_mm[1] - s.start_mm[1]) >= 1e-9) {
                m_.pos_mm = s.end_mm;
                emitted = true;
                push(p, std::move(s), line_no);
            }
        }
        move(NcMotion::Rapid, r_level);
        switch (m_.cycle) {
            case 81: case 82: case 86:
                move(NcMotion::Linear, bottom);
                if (m_.cycle == 82) pause(m_.dwell_s);
                move(NcMotion::Rapid, back, m_.cycle == 86);   // G86: spindle stopped at the bottom
                break;
            case 85: case 89:
                move(NcMotion::Linear, bottom);
                if (m_.cycle == 89) pause(m_.dwell_s);
                move(NcMotion::Linear, r_level);   // feed out
                move(NcMotion::Rapid, back);
                break;
            case 83: case 73: {
                // G83: every peck returns to R and comes back by rapid to the clearance above the
                // last depth; G73: every peck retracts by peck_retract_mm only.
                double depth = r_level;
                while (depth > bottom + 1e-9) {
                    const double next = std::max(bottom, depth - *m_.q_mm);
                    if (depth < r_level) {
                        if (m_.cycle == 83) {
                            move(NcMotion::Rapid, r_level);
                            move(NcMotion::Rapid, std::min(r_level, depth + opt_.peck_clearance_mm));
                        } else {
                            move(NcMotion::Rapid, std::min(r_level, depth + opt_.peck_retract_mm));
                        }
                    }
                    move(NcMotion::Linear, next);
                    depth = next;
                }
                move(NcMotion::Rapid, back);
                break;
            }
            default: fail(line_no, code, "unknown canned cycle");
        }
        if (!emitted) push(p, std::move(b), line_no);
    }

    void make_arc(NcBlock& b, const std::string& line, std::size_t line_no, const NcWord* const center[3], const NcWord* r_word) {
        const std::array<int, 3> axes = m_.plane == 17 ? std::array<int, 3>{0, 1, 2}
                                        : m_.plane == 18 ? std::array<int, 3>{2, 0, 1}
                                                         : std::array<int, 3>{1, 2, 0};
        b.plane_axes = axes;
        const int a = axes[0], c = axes[1], n = axes[2];
        const std::string code = b.motion == NcMotion::ArcCw ? "G02" : "G03";
        for (int k = 0; k < 3; ++k) {
            if (!m_.known[k] && (k == a || k == c)) fail(line_no, code, "arc before the position of its plane axes is known");
        }
        if (center[n]) fail(line_no, word_text(line, *center[n]), fmt::format("not an arc centre word in the G{} plane", m_.plane));
        const bool ccw = b.motion == NcMotion::ArcCcw;
        const double sa = b.start_mm[a], sc = b.start_mm[c], ea = b.end_mm[a], ec = b.end_mm[c];
        double ca = 0, cc = 0;
        if (r_word) {
            if (center[a] || center[c]) fail(line_no, word_text(line, *r_word), "give R or I/J/K, not both");
            const double r = bounded_length_mm(line_no, line, *r_word);
            const double da = ea - sa, dc = ec - sc, d = std::hypot(da, dc);
            if (d < 1e-9) fail(line_no, word_text(line, *r_word), "an R arc cannot be a full circle (use I/J/K)");
            if (d > 2 * std::abs(r) + arc_tolerance_mm(std::abs(r)))
                fail(line_no, word_text(line, *r_word), fmt::format("radius {:.4f} mm is shorter than half the chord {:.4f} mm", std::abs(r), d / 2));
            const double h = std::sqrt(std::max(0.0, r * r - d * d / 4));
            // Left of the chord for a counter-clockwise arc up to 180 deg; R < 0 asks for the long way round.
            const double side = (ccw ? 1.0 : -1.0) * (r > 0 ? 1.0 : -1.0);
            ca = (sa + ea) / 2 - side * h * dc / d;
            cc = (sc + ec) / 2 + side * h * da / d;
        } else {
            // A centre word left out is the start's coordinate, in both modes.
            const auto& offset = opt_.work_offsets_mm.at(m_.wcs);
            auto centre = [&](int axis, double start) {
                if (!center[axis]) return start;
                const double v = bounded_length_mm(line_no, line, *center[axis]);
                return m_.absolute_centers ? v + offset[axis] : start + v;
            };
            ca = centre(a, sa);
            cc = centre(c, sc);
            const double r0 = std::hypot(sa - ca, sc - cc), r1 = std::hypot(ea - ca, ec - cc);
            if (r0 < 1e-9) fail(line_no, code, "arc centre equals its start point");
            const double tol = arc_tolerance_mm(r0);
            if (std::abs(r0 - r1) > tol)
                fail(line_no, code,
                     fmt::format("end point is not on the arc: radius {:.4f} mm at the start, {:.4f} mm at the end (tolerance {:.4f} mm{})", r0,
                                 r1, tol, m_.absolute_centers ? "; centres are absolute (G90.1)" : "; centres are incremental (G91.1)"));
        }
        b.center_mm = b.start_mm;
        b.center_mm[a] = ca;
        b.center_mm[c] = cc;
        const double a0 = std::atan2(sc - cc, sa - ca), a1 = std::atan2(ec - cc, ea - ca);
        const double two_pi = 2 * std::numbers::pi;
        double sweep = a1 - a0;
        if (ccw) {
            while (sweep <= 1e-12) sweep += two_pi;
        } else {
            while (sweep >= -1e-12) sweep -= two_pi;
        }
        // A numerically closed I/J/K arc is a full circle, not a sliver.
        if (!r_word && std::hypot(ea - sa, ec - sc) < 1e-9) sweep = ccw ? two_pi : -two_pi;
        b.sweep_rad = sweep;
    }

    double arc_tolerance_mm(double radius_mm) const { return opt_.arc_tolerance_mm + opt_.arc_tolerance_rel * radius_mm; }

    // Axes not yet given at a block: they sat where the program first put them absolutely.
    void back_fill(NcProgram& p) const {
        for (std::size_t i = 0; i < p.blocks.size(); ++i)
            for (int a = 0; a < 3; ++a)
                if (!known_at_block_[i][a] && m_.known[a] && i < became_known_at_[a]) p.blocks[i].start_mm[a] = p.blocks[i].end_mm[a] = m_first_mm_[a];
    }

    std::string file_;
    const NcReadOptions& opt_;
    const NcLimits& lim_;
    std::vector<std::pair<char, double>> ignore_;
    Modal m_;
    bool ended_ = false, seen_words_ = false;
    std::vector<std::array<bool, 3>> known_at_block_;
    std::array<std::size_t, 3> became_known_at_{};
    std::array<double, 3> m_first_mm_{};
    double path_mm_ = 0, duration_s_ = 0;
    std::string culprit_;   // the word a work bound names: the block's first axis word, else its first word
    std::array<bool, 3> rotary_allowed_{}, rotary_named_{};   // A, B, C: the machine has it, the program names it
};

}  // namespace

void check_rapid_feed(double rapid_mm_min, const NcLimits& limits, const std::string& what) {
    if (!(rapid_mm_min >= limits.min_rapid_mm_min && rapid_mm_min <= limits.max_rapid_mm_min))
        throw NcProgramError(fmt::format("{}: {:g} mm/min is outside the physical range {:g}..{:g} mm/min", what, rapid_mm_min,
                                         limits.min_rapid_mm_min, limits.max_rapid_mm_min));
}

std::map<std::string, std::array<double, 3>> default_work_offsets(const double setup_offset_mm[3]) {
    return {{"G54", {-setup_offset_mm[0], -setup_offset_mm[1], -setup_offset_mm[2]}}};
}

NcProgram parse_nc_program(const std::string& text, const std::string& file, const NcReadOptions& opt) {
    Parser parser(file, opt);
    return parser.parse(text);
}

NcProgram read_nc_program(const std::string& path, const NcReadOptions& opt) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw NcProgramError(fmt::format("{}: cannot open the NC program", path));
    std::ostringstream ss;
    ss << in.rdbuf();
    if (ss.str().empty()) throw NcProgramError(fmt::format("{}: the NC program is empty", path));
    return parse_nc_program(ss.str(), path, opt);
}

std::vector<int> program_tools(const NcProgram& program) {
    std::vector<int> out;
    for (const NcBlock& b : program.blocks)
        if (b.tool >= 0 && std::find(out.begin(), out.end(), b.tool) == out.end()) out.push_back(b.tool);
    return out;
}

bool block_turns(const NcBlock& b) { return b.start_deg != b.end_deg; }

bool block_moves(const NcBlock& b) {
    return (b.motion == NcMotion::Rapid || b.motion == NcMotion::Linear || b.motion == NcMotion::ArcCw ||
            b.motion == NcMotion::ArcCcw) &&
           (block_length_mm(b) > 0 || block_turns(b));
}

double block_joint_length(const NcBlock& b) {
    const double path = block_length_mm(b);
    if (!block_turns(b)) return path;
    return std::hypot(path, std::hypot(b.end_deg[0] - b.start_deg[0], b.end_deg[1] - b.start_deg[1], b.end_deg[2] - b.start_deg[2]));
}

double block_time_s(const NcBlock& b, double rapid_mm_min) {
    if (!block_moves(b)) return 0;
    if (b.feed_time_s > 0) return b.feed_time_s;   // G93, a rotary feed rule, or a piece of a joint-space block
    if (b.motion == NcMotion::Rapid) return block_joint_length(b) / (rapid_mm_min / 60.0);
    return block_length_mm(b) / (b.feed_mm_min / 60.0);
}

std::optional<RotaryFeed> parse_rotary_feed(const std::string& text) {
    if (text == "combined") return RotaryFeed::Combined;
    if (text == "linear_only") return RotaryFeed::LinearOnly;
    return std::nullopt;
}

const char* rotary_feed_name(RotaryFeed f) { return f == RotaryFeed::Combined ? "combined" : "linear_only"; }

double block_length_mm(const NcBlock& b) {
    switch (b.motion) {
        case NcMotion::Rapid:
        case NcMotion::Linear:
            return std::hypot(b.end_mm[0] - b.start_mm[0], b.end_mm[1] - b.start_mm[1], b.end_mm[2] - b.start_mm[2]);
        case NcMotion::ArcCw:
        case NcMotion::ArcCcw: {
            const int a = b.plane_axes[0], c = b.plane_axes[1], n = b.plane_axes[2];
            const double r0 = std::hypot(b.start_mm[a] - b.center_mm[a], b.start_mm[c] - b.center_mm[c]);
            const double r1 = std::hypot(b.end_mm[a] - b.center_mm[a], b.end_mm[c] - b.center_mm[c]);
            return std::hypot(0.5 * (r0 + r1) * std::abs(b.sweep_rad), b.end_mm[n] - b.start_mm[n]);
        }
        default: return 0;
    }
}

void block_point(const NcBlock& b, double u, double pos_mm[3], double tangent[3]) {
    u = std::clamp(u, 0.0, 1.0);
    if (b.motion == NcMotion::ArcCw || b.motion == NcMotion::ArcCcw) {
        const int a = b.plane_axes[0], c = b.plane_axes[1], n = b.plane_axes[2];
        const double r0 = std::hypot(b.start_mm[a] - b.center_mm[a], b.start_mm[c] - b.center_mm[c]);
        const double r1 = std::hypot(b.end_mm[a] - b.center_mm[a], b.end_mm[c] - b.center_mm[c]);
        const double a0 = std::atan2(b.start_mm[c] - b.center_mm[c], b.start_mm[a] - b.center_mm[a]);
        const double ang = a0 + u * b.sweep_rad, r = r0 + u * (r1 - r0);
        const double dn = b.end_mm[n] - b.start_mm[n];
        pos_mm[a] = b.center_mm[a] + r * std::cos(ang);
        pos_mm[c] = b.center_mm[c] + r * std::sin(ang);
        pos_mm[n] = b.start_mm[n] + u * dn;
        double t[3];
        t[a] = -r * std::sin(ang) * b.sweep_rad + (r1 - r0) * std::cos(ang);
        t[c] = r * std::cos(ang) * b.sweep_rad + (r1 - r0) * std::sin(ang);
        t[n] = dn;
        const double len = std::hypot(t[0], t[1], t[2]);
        for (int k = 0; k < 3; ++k) tangent[k] = len > 0 ? t[k] / len : 0.0;
        return;
    }
    const double len = block_length_mm(b);
    for (int k = 0; k < 3; ++k) {
        pos_mm[k] = b.start_mm[k] + u * (b.end_mm[k] - b.start_mm[k]);
        tangent[k] = len > 0 ? (b.end_mm[k] - b.start_mm[k]) / len : 0.0;
    }
}

double representable_feed_mm_min(const NcBlock& b, double feed_mm_min) {
    if (b.inch) return std::floor(feed_mm_min / kMmPerInch * 10 + 1e-9) / 10 * kMmPerInch;
    return std::floor(feed_mm_min + 1e-9);
}

namespace {

std::string feed_text(const NcBlock& b, double feed_mm_min) {
    const double v = b.inch ? feed_mm_min / kMmPerInch : feed_mm_min;
    const double rounded = std::round(v * 10) / 10;
    return std::abs(rounded - std::round(rounded)) < 1e-9 ? fmt::format("F{:.0f}", rounded) : fmt::format("F{:.1f}", rounded);
}

bool feed_motion(const NcBlock& b) {
    return b.motion == NcMotion::Linear || b.motion == NcMotion::ArcCw || b.motion == NcMotion::ArcCcw;
}

}  // namespace

std::string rewrite_feeds(const NcProgram& program, const std::vector<double>& feed_mm_min) {
    if (feed_mm_min.size() != program.blocks.size())
        throw std::invalid_argument(fmt::format("rewrite_feeds: {} feeds for {} blocks", feed_mm_min.size(), program.blocks.size()));
    std::vector<std::string> lines = program.lines;
    double modal_out = 0;   // the feed the rewritten program has in force, mm/min
    // A source line is one block, or the pieces of a canned cycle: its feed is that of its first
    // feed motion (a cycle's rapids and dwells have none).
    for (std::size_t i = 0; i < program.blocks.size();) {
        std::size_t end = i;
        double want = 0;
        for (; end < program.blocks.size() && program.blocks[end].line == program.blocks[i].line; ++end)
            if (want <= 0 && feed_motion(program.blocks[end]))
                want = feed_mm_min[end] > 0 ? feed_mm_min[end] : program.blocks[end].feed_mm_min;
        const NcBlock& b = program.blocks[i];
        i = end;
        std::string& line = lines[b.line - 1];
        const auto f = std::find_if(b.words.begin(), b.words.end(), [](const NcWord& w) { return w.letter == 'F'; });
        if (f != b.words.end()) {
            // Replace in place; later words on the line do not move in the token stream.
            const std::string text = want > 0 ? feed_text(b, want) : program.lines[b.line - 1].substr(f->column, f->length);
            line = program.lines[b.line - 1].substr(0, f->column) + text + program.lines[b.line - 1].substr(f->column + f->length);
            modal_out = want > 0 ? want : b.feed_mm_min;
        } else if (want > 0 && std::abs(want - modal_out) > 1e-6) {
            const NcWord& last = b.words.back();
            const std::size_t at = last.column + last.length;
            // Follow the block's own style: words separated by blanks, or packed ("G01X10.F500").
            const bool spaced = b.words.size() < 2 || b.words[1].column > b.words[0].column + b.words[0].length;
            line = line.substr(0, at) + (spaced ? " " : "") + feed_text(b, want) + line.substr(at);
            modal_out = want;
        }
    }
    std::string out;
    for (std::size_t i = 0; i < lines.size(); ++i) {
        out += lines[i];
        if (i + 1 < lines.size() || program.final_newline) out += '\n';
    }
    return out;
}

std::vector<std::string> nc_tokens(const std::string& line) { return tokenize(line).texts; }

}  // namespace cutload::motion_io
