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
constexpr double kArcRadiusTolerance_mm = 0.01;

struct LineWords {
    std::vector<NcWord> words;
    std::vector<std::string> texts;   // each word as written
    std::string error_word, error_what;
};

// Splits a line into words; comments "( ... )" and "; ..." are dropped. On the first malformed
// character the error fields are set and scanning stops.
LineWords tokenize(const std::string& line) {
    LineWords out;
    std::size_t i = 0;
    const std::size_t n = line.size();
    auto fail = [&](std::string word, std::string what) {
        out.error_word = std::move(word);
        out.error_what = std::move(what);
    };
    while (i < n) {
        const char c = line[i];
        if (c == ' ' || c == '\t' || c == '\r') {
            ++i;
        } else if (c == '(') {
            const std::size_t close = line.find(')', i);
            if (close == std::string::npos) return fail(line.substr(i), "comment without ')'"), out;
            i = close + 1;
        } else if (c == ';') {
            break;
        } else if (c == '%' && out.words.empty()) {
            ++i;
        } else if (c == '/' && out.words.empty()) {
            return fail("/", "optional block skip ('/') is not supported"), out;
        } else if (std::isalpha(static_cast<unsigned char>(c))) {
            NcWord w;
            w.letter = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
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
            w.length = j - i;
            out.words.push_back(w);
            out.texts.push_back(line.substr(i, j - i));
            i = j;
        } else if (c == '#') {
            std::size_t e = i + 1;
            while (e < n && std::isalnum(static_cast<unsigned char>(line[e]))) ++e;
            return fail(line.substr(i, e - i), "macro variables are not supported"), out;
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
            throw NcProgramError(fmt::format("ignore word '{}': expected a letter or a code like G28", s));
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
            throw NcProgramError(fmt::format("ignore word '{}': expected a letter or a code like G28", s));
        }
    }
    return out;
}

// Why a G or M code is refused; empty: supported.
std::string unsupported_g(double g) {
    const int code = static_cast<int>(std::lround(g * 10));
    switch (code) {
        case 410: case 420: return "cutter radius compensation is not supported (the path would be offset by the tool radius)";
        case 730: case 740: case 760: case 810: case 820: case 830: case 840: case 850: case 860: case 870: case 880: case 890:
            return "canned cycles are not supported (expand the cycle into G00/G01 moves)";
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

// Parser state carried from block to block (modal values).
struct Modal {
    NcMotion motion = NcMotion::Rapid;   // FANUC parameter 3402#0 = 0: G00 at power-up
    int plane = 17;
    bool inch = false;
    bool incremental = false;
    std::string wcs = "G54";
    double feed_mm_min = 0;
    double speed_rpm = 0;
    int direction = 0;                   // +1 M03, -1 M04, 0 stopped
    std::array<double, 3> pos_mm{};
    std::array<bool, 3> known{};
    double tool = -1;
};

class Parser {
public:
    Parser(const std::string& file, const NcReadOptions& opt) : file_(file), opt_(opt), ignore_(parse_ignore(opt.ignore_words)) {
        if (opt.start_mm) {
            m_.pos_mm = *opt.start_mm;
            m_.known = {true, true, true};
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
        return p;
    }

private:
    [[noreturn]] void fail(std::size_t line, const std::string& word, const std::string& what) const {
        throw NcProgramError(fmt::format("{}:{}: word '{}': {}", file_, line, word, what));
    }

    double length_mm(const NcWord& w) const {
        double v = w.value;
        if (opt_.decimal_less_is_increment && !w.has_decimal_point) v *= m_.inch ? 1e-4 : 1e-3;
        return m_.inch ? v * kMmPerInch : v;
    }

    void parse_line(NcProgram& p, std::size_t line_no, const std::string& line) {
        LineWords lw = tokenize(line);
        if (!lw.error_word.empty()) fail(line_no, lw.error_word, lw.error_what);
        std::vector<NcWord> words;
        for (const NcWord& w : lw.words)
            if (!matches_ignore(w, ignore_)) words.push_back(w);
        if (lw.words.empty()) return;

        NcBlock b;
        b.line = line_no;
        b.words = lw.words;
        b.name = fmt::format("L{}", line_no);
        const NcWord* axis[3] = {nullptr, nullptr, nullptr};
        const NcWord* center[3] = {nullptr, nullptr, nullptr};
        const NcWord *r_word = nullptr, *f_word = nullptr, *s_word = nullptr, *p_word = nullptr;
        bool dwell = false, machine_coords = false, motion_code = false;
        int new_plane = 0;
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
                case 'H': break;   // tool length offset number: the tool length is part of the work offset
                case 'T':
                    if (m_.tool >= 0 && std::abs(m_.tool - w.value) > 1e-9)
                        fail(line_no, text, "a second tool is not supported (one run spec describes one tool)");
                    m_.tool = w.value;
                    break;
                case 'G': {
                    const double g = w.value;
                    if (is_code(w, 'G', 0) || is_code(w, 'G', 1) || is_code(w, 'G', 2) || is_code(w, 'G', 3)) {
                        static constexpr NcMotion kinds[4] = {NcMotion::Rapid, NcMotion::Linear, NcMotion::ArcCw, NcMotion::ArcCcw};
                        m_.motion = kinds[static_cast<int>(std::lround(g))];
                        motion_code = true;
                    } else if (is_code(w, 'G', 4)) {
                        dwell = true;
                    } else if (is_code(w, 'G', 17) || is_code(w, 'G', 18) || is_code(w, 'G', 19)) {
                        new_plane = static_cast<int>(std::lround(g));
                    } else if (is_code(w, 'G', 20) || is_code(w, 'G', 21)) {
                        m_.inch = is_code(w, 'G', 20);
                    } else if (is_code(w, 'G', 90) || is_code(w, 'G', 91)) {
                        m_.incremental = is_code(w, 'G', 91);
                    } else if (is_code(w, 'G', 53)) {
                        machine_coords = true;
                    } else if (g >= 54 - 1e-9 && g <= 59 + 1e-9 && std::abs(g - std::round(g)) < 1e-9) {
                        m_.wcs = fmt::format("G{}", static_cast<int>(std::lround(g)));
                        if (!opt_.work_offsets_mm.count(m_.wcs))
                            fail(line_no, text, "no offset is set for this work coordinate system (set its offset: --work-offset in the CLI, nc_options.work_offsets_mm in the API)");
                    } else if (is_code(w, 'G', 40) || is_code(w, 'G', 43) || is_code(w, 'G', 44) || is_code(w, 'G', 49) ||
                               is_code(w, 'G', 9) || is_code(w, 'G', 61) || is_code(w, 'G', 64) || is_code(w, 'G', 80) ||
                               is_code(w, 'G', 94)) {
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
                    else if (mc == 2 || mc == 30) ended_ = true;
                    else if (mc == 98 || mc == 99) fail(line_no, text, "subprograms are not supported");
                    else if (mc != 0 && mc != 1 && mc != 6 && mc != 7 && mc != 8 && mc != 9)
                        fail(line_no, text, "this M code is not supported");
                    break;
                }
                case 'D': fail(line_no, text, "cutter compensation numbers (D) are not supported");
                case 'A': case 'B': case 'C': case 'U': case 'V': case 'W':
                    fail(line_no, text, "only the linear axes X, Y and Z are supported");
                default: fail(line_no, text, "this address is not supported");
            }
        }
        if (new_plane) m_.plane = new_plane;
        if (f_word) {
            if (!(f_word->value > 0)) fail(line_no, word_text(line, *f_word), "feed must be > 0");
            m_.feed_mm_min = m_.inch ? f_word->value * kMmPerInch : f_word->value;
            b.has_feed_word = true;
        }
        if (s_word) {
            if (s_word->value < 0) fail(line_no, word_text(line, *s_word), "spindle speed must be >= 0");
            m_.speed_rpm = s_word->value;
        }
        b.feed_mm_min = m_.feed_mm_min;
        b.spindle_rpm = m_.direction * m_.speed_rpm;
        b.inch = m_.inch;
        b.start_mm = b.end_mm = m_.pos_mm;
        known_at_block_.push_back(m_.known);

        if (dwell) {
            if (axis[1] || axis[2] || center[0] || center[1] || center[2] || r_word)
                fail(line_no, "G04", "a dwell block takes only X (s) or P (ms)");
            if (axis[0] && p_word) fail(line_no, word_text(line, *p_word), "give the dwell as X (s) or P (ms), not both");
            if (axis[0]) b.dwell_s = axis[0]->value * (opt_.decimal_less_is_increment && !axis[0]->has_decimal_point ? 1e-3 : 1.0);
            else if (p_word) b.dwell_s = p_word->value * 1e-3;
            else fail(line_no, "G04", "a dwell needs X (s) or P (ms)");
            if (b.dwell_s < 0) fail(line_no, "G04", "dwell time must be >= 0");
            b.motion = NcMotion::Dwell;
            p.blocks.push_back(std::move(b));
            return;
        }
        if (p_word) fail(line_no, word_text(line, *p_word), "P is supported only as a G04 dwell time");

        const bool has_axes = axis[0] || axis[1] || axis[2];
        const bool arc = m_.motion == NcMotion::ArcCw || m_.motion == NcMotion::ArcCcw;
        const bool has_center = center[0] || center[1] || center[2];
        if (!arc && (has_center || r_word)) {
            const NcWord& w = r_word ? *r_word : *(center[0] ? center[0] : center[1] ? center[1] : center[2]);
            fail(line_no, word_text(line, w), "arc words need G02 or G03");
        }
        if (!has_axes && !(arc && has_center)) {
            if (motion_code && arc && r_word) fail(line_no, word_text(line, *r_word), "an R arc needs an end point");
            p.blocks.push_back(std::move(b));
            return;
        }
        if (machine_coords && m_.incremental) fail(line_no, "G53", "G53 takes absolute machine positions (G90)");
        if (machine_coords && m_.motion != NcMotion::Rapid && m_.motion != NcMotion::Linear)
            fail(line_no, "G53", "G53 is supported with G00 and G01 only");

        const auto wcs = opt_.work_offsets_mm.find(m_.wcs);
        if (wcs == opt_.work_offsets_mm.end())
            fail(line_no, m_.wcs, "no offset is set for this work coordinate system, active since the program start (set its offset: --work-offset in the CLI, nc_options.work_offsets_mm in the API)");
        const auto& offset = wcs->second;
        std::array<double, 3> target = m_.pos_mm;
        for (int a = 0; a < 3; ++a) {
            if (!axis[a]) continue;
            const double v = length_mm(*axis[a]);
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
        if (m_.motion != NcMotion::Rapid && !(m_.feed_mm_min > 0)) fail(line_no, word_text(line, words.front()), "no feed rate (F) is in force for this move");
        b.motion = m_.motion;
        b.end_mm = target;
        if (arc) make_arc(b, line, line_no, center, r_word);
        m_.pos_mm = target;
        p.blocks.push_back(std::move(b));
    }

    void make_arc(NcBlock& b, const std::string& line, std::size_t line_no, const NcWord* const center[3], const NcWord* r_word) {
        const std::array<int, 3> axes = m_.plane == 17 ? std::array<int, 3>{0, 1, 2}
                                        : m_.plane == 18 ? std::array<int, 3>{2, 0, 1}
                                                         : std::array<int, 3>{1, 2, 0};
        b.plane_axes = axes;
        const int a = axes[0], c = axes[1], n = axes[2];
        for (int k = 0; k < 3; ++k) {
            if (!m_.known[k] && (k == a || k == c))
                fail(line_no, b.motion == NcMotion::ArcCw ? "G02" : "G03", "arc before the position of its plane axes is known");
        }
        if (center[n]) fail(line_no, word_text(line, *center[n]), fmt::format("not an arc centre word in the G{} plane", m_.plane));
        const bool ccw = b.motion == NcMotion::ArcCcw;
        const double sa = b.start_mm[a], sc = b.start_mm[c], ea = b.end_mm[a], ec = b.end_mm[c];
        double ca = 0, cc = 0;
        if (r_word) {
            if (center[a] || center[c]) fail(line_no, word_text(line, *r_word), "give R or I/J/K, not both");
            const double r = length_mm(*r_word);
            const double da = ea - sa, dc = ec - sc, d = std::hypot(da, dc);
            if (d < 1e-9) fail(line_no, word_text(line, *r_word), "an R arc cannot be a full circle (use I/J/K)");
            if (d > 2 * std::abs(r) + kArcRadiusTolerance_mm)
                fail(line_no, word_text(line, *r_word), fmt::format("radius {:.4f} mm is shorter than half the chord {:.4f} mm", std::abs(r), d / 2));
            const double h = std::sqrt(std::max(0.0, r * r - d * d / 4));
            // Left of the chord for a counter-clockwise arc up to 180 deg; R < 0 asks for the long way round.
            const double side = (ccw ? 1.0 : -1.0) * (r > 0 ? 1.0 : -1.0);
            ca = (sa + ea) / 2 - side * h * dc / d;
            cc = (sc + ec) / 2 + side * h * da / d;
        } else {
            ca = sa + (center[a] ? length_mm(*center[a]) : 0.0);
            cc = sc + (center[c] ? length_mm(*center[c]) : 0.0);
            const double r0 = std::hypot(sa - ca, sc - cc), r1 = std::hypot(ea - ca, ec - cc);
            if (r0 < 1e-9) fail(line_no, b.motion == NcMotion::ArcCw ? "G02" : "G03", "arc centre equals its start point");
            if (std::abs(r0 - r1) > kArcRadiusTolerance_mm)
                fail(line_no, b.motion == NcMotion::ArcCw ? "G02" : "G03",
                     fmt::format("end point is not on the arc: radius {:.4f} mm at the start, {:.4f} mm at the end", r0, r1));
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

    // Axes not yet given at a block: they sat where the program first put them absolutely.
    void back_fill(NcProgram& p) const {
        for (std::size_t i = 0; i < p.blocks.size(); ++i)
            for (int a = 0; a < 3; ++a)
                if (!known_at_block_[i][a] && m_.known[a] && i < became_known_at_[a]) p.blocks[i].start_mm[a] = p.blocks[i].end_mm[a] = m_first_mm_[a];
    }

    std::string file_;
    const NcReadOptions& opt_;
    std::vector<std::pair<char, double>> ignore_;
    Modal m_;
    bool ended_ = false;
    std::vector<std::array<bool, 3>> known_at_block_;
    std::array<std::size_t, 3> became_known_at_{};
    std::array<double, 3> m_first_mm_{};
};

}  // namespace

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

bool block_moves(const NcBlock& b) {
    return (b.motion == NcMotion::Rapid || b.motion == NcMotion::Linear || b.motion == NcMotion::ArcCw ||
            b.motion == NcMotion::ArcCcw) &&
           block_length_mm(b) > 0;
}

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
    for (std::size_t i = 0; i < program.blocks.size(); ++i) {
        const NcBlock& b = program.blocks[i];
        const double want = feed_motion(b) ? (feed_mm_min[i] > 0 ? feed_mm_min[i] : b.feed_mm_min) : 0.0;
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
