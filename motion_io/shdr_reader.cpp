// Stage "parse + validate" for MTConnect SHDR streams (adapter output):
//   timestamp|key|value|key|value...         samples and events
//   timestamp|key|LEVEL|code|qualifier|severity|text   conditions (skipped)
//   timestamp|@ASSET@|id|type|--multiline--XXXX ... --multiline--XXXX   assets (skipped)
//   * command: value                        agent commands (skipped)
// Which data items feed which channel comes from a key map (built-in defaults or a JSON file,
// docs/formats.md). A first pass collects only the key names present, so the highest-priority
// candidate that the log actually contains is chosen; both passes stream line by line.
#include "pipeline.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <charconv>
#include <cmath>
#include <fstream>
#include <set>

namespace cutload::motion_io::detail {
namespace {

struct KeyMap {
    std::vector<std::string> position, x, y, z, feed, spindle, block;
    std::string length_unit = "mm";
    std::string feed_unit = "mm/s";   // MTConnect's unit for PATH_FEEDRATE
    std::string spindle_unit = "rpm";
};

KeyMap default_map() {
    KeyMap m;
    m.position = {"path_pos", "p1LPathPos", "Lp1LPathPos", "PathPos"};
    m.x = {"X1actw", "Xact", "Xabs", "Xpos", "X1actm"};
    m.y = {"Y1actw", "YI1actw", "Yact", "Yabs", "Ypos", "Y1actm", "YI1actm"};
    m.z = {"Z1actw", "Zact", "Zabs", "Zpos", "Z1actm"};
    m.feed = {"p1Fact", "path_feedrate", "Fact", "Frt"};
    // The milling (tool) spindle first: on Okuma multitasking controls S6 turns the cutter while
    // S1/S2 turn the workpiece; a plain machining centre only has S1.
    m.spindle = {"S6speed", "S1speed", "Sspeed", "spindle_speed", "Srpm"};
    m.block = {"p1BlockNumber", "line", "block", "p1linenumber"};
    return m;
}

KeyMap load_map(const std::string& path) {
    KeyMap m = default_map();
    if (path.empty()) return m;
    std::ifstream in(path);
    if (!in) throw IngestError(fmt::format("{}: cannot open SHDR map file", path));
    nlohmann::json j;
    try {
        in >> j;
    } catch (const nlohmann::json::parse_error& e) {
        throw IngestError(fmt::format("{}: not valid JSON: {}", path, e.what()));
    }
    if (!j.is_object()) throw IngestError(fmt::format("{}: expected a JSON object mapping channels to keys", path));
    const std::map<std::string, std::vector<std::string>*> lists{
        {"position", &m.position}, {"x", &m.x}, {"y", &m.y}, {"z", &m.z},
        {"feed", &m.feed}, {"spindle", &m.spindle}, {"block", &m.block}};
    for (const auto& [key, value] : j.items()) {
        if (key == "units") {
            if (!value.is_object()) throw IngestError(fmt::format("{}: key 'units': expected an object", path));
            for (const auto& [u, v] : value.items()) {
                if (!v.is_string()) throw IngestError(fmt::format("{}: key 'units.{}': expected a string", path, u));
                std::string* dst = u == "length" ? &m.length_unit : u == "feed" ? &m.feed_unit
                                 : u == "spindle" ? &m.spindle_unit : nullptr;
                if (!dst) throw IngestError(fmt::format("{}: key 'units.{}': expected length, feed or spindle", path, u));
                *dst = v.get<std::string>();
            }
            continue;
        }
        const auto it = lists.find(key);
        if (it == lists.end())
            throw IngestError(fmt::format("{}: unknown key '{}' (expected position, x, y, z, feed, spindle, block, units)",
                                          path, key));
        std::vector<std::string> keys;
        if (value.is_string()) {
            keys.push_back(value.get<std::string>());
        } else if (value.is_array()) {
            for (const auto& k : value) {
                if (!k.is_string()) throw IngestError(fmt::format("{}: key '{}': expected strings", path, key));
                keys.push_back(k.get<std::string>());
            }
        } else {
            throw IngestError(fmt::format("{}: key '{}': expected a data-item key or a list of keys", path, key));
        }
        *it->second = std::move(keys);
    }
    return m;
}

void split_pipes(std::string_view line, std::vector<std::string_view>& out) {
    out.clear();
    std::size_t start = 0;
    while (true) {
        const std::size_t bar = line.find('|', start);
        if (bar == std::string_view::npos) {
            out.push_back(line.substr(start));
            return;
        }
        out.push_back(line.substr(start, bar - start));
        start = bar + 1;
    }
}

constexpr std::string_view kMultiline = "--multiline--";

bool is_condition(const std::vector<std::string_view>& f) {
    if (f.size() != 7) return false;
    if (f[2] == "NORMAL" || f[2] == "WARNING" || f[2] == "FAULT") return true;
    return f[2] == "UNAVAILABLE" && f[3].empty() && f[4].empty() && f[5].empty() && f[6].empty();
}

// Days since 1970-01-01 of a civil date (proleptic Gregorian).
std::int64_t days_from_civil(std::int64_t y, unsigned m, unsigned d) {
    y -= m <= 2;
    const std::int64_t era = (y >= 0 ? y : y - 399) / 400;
    const auto yoe = static_cast<unsigned>(y - era * 400);
    const unsigned doy = (153 * (m + (m > 2 ? -3 : 9)) + 2) / 5 + d - 1;
    const unsigned doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    return era * 146097 + static_cast<std::int64_t>(doe) - 719468;
}

struct Stamp {
    std::int64_t sec = 0;
    double frac = 0;
};

bool parse_int(std::string_view s, int& v) {
    const auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
    return ec == std::errc() && p == s.data() + s.size();
}

// "2022-08-08T13:51:34.7167146Z", optionally followed by "@duration".
std::optional<Stamp> parse_stamp(std::string_view s) {
    if (const auto at = s.find('@'); at != std::string_view::npos) s = s.substr(0, at);
    if (!s.empty() && s.back() == 'Z') s.remove_suffix(1);
    if (s.size() < 19 || s[4] != '-' || s[7] != '-' || (s[10] != 'T' && s[10] != ' ') || s[13] != ':' || s[16] != ':')
        return std::nullopt;
    int y, mo, d, h, mi, se;
    if (!parse_int(s.substr(0, 4), y) || !parse_int(s.substr(5, 2), mo) || !parse_int(s.substr(8, 2), d) ||
        !parse_int(s.substr(11, 2), h) || !parse_int(s.substr(14, 2), mi) || !parse_int(s.substr(17, 2), se))
        return std::nullopt;
    Stamp st;
    st.sec = days_from_civil(y, static_cast<unsigned>(mo), static_cast<unsigned>(d)) * 86400 + h * 3600 + mi * 60 + se;
    if (s.size() > 19) {
        if (s[19] != '.') return std::nullopt;
        double f = 0;
        const std::string frac = "0" + std::string(s.substr(19));
        const auto [p, ec] = std::from_chars(frac.data(), frac.data() + frac.size(), f);
        if (ec != std::errc() || p != frac.data() + frac.size()) return std::nullopt;
        st.frac = f;
    }
    return st;
}

const std::string* first_present(const std::vector<std::string>& candidates, const std::set<std::string, std::less<>>& seen) {
    for (const auto& k : candidates)
        if (seen.count(k)) return &k;
    return nullptr;
}

class ShdrReader {
public:
    ShdrReader(const std::string& path, const ReadOptions& opt, Diagnostics& diag, BlockTable& blocks, RecordSink& out)
        : path_(path), opt_(opt), diag_(diag), blocks_(blocks), out_(out), map_(load_map(opt.map_file)) {}

    void run() {
        choose_keys(scan_keys());
        std::ifstream in(path_, std::ios::binary);
        if (!in) diag_.fail(0, "cannot open file");
        std::string line;
        std::size_t line_no = 0;
        std::string multiline_end;
        while (std::getline(in, line)) {
            ++line_no;
            if (!line.empty() && line.back() == '\r') line.pop_back();
            if (!multiline_end.empty()) {
                if (line == multiline_end) multiline_end.clear();
                continue;
            }
            if (line.empty() || line.front() == '*') continue;
            split_pipes(line, fields_);
            if (fields_.size() < 3) {
                diag_.warn("shdr_short_line", line_no, "line without 'timestamp|key|value'; skipped");
                continue;
            }
            if (fields_.back().substr(0, kMultiline.size()) == kMultiline) {
                multiline_end = std::string(fields_.back());
                continue;
            }
            if (fields_[1].substr(0, 1) == "@" || is_condition(fields_)) continue;
            const auto stamp = parse_stamp(fields_[0]);
            if (!stamp)
                diag_.fail(line_no, fmt::format("'{}' is not an ISO 8601 time stamp (expected e.g. 2022-08-08T13:51:34.7167146Z)",
                                                fields_[0]));
            if (!have_origin_) {
                origin_sec_ = stamp->sec;
                have_origin_ = true;
            }
            const double t_s = static_cast<double>(stamp->sec - origin_sec_) + stamp->frac;
            if ((fields_.size() - 1) % 2 != 0)
                diag_.warn("shdr_odd_fields", line_no, "odd number of key/value fields; the last one ignored");
            for (std::size_t i = 1; i + 1 < fields_.size(); i += 2) handle(fields_[i], fields_[i + 1], t_s, line_no);
        }
        if (!multiline_end.empty())
            diag_.warn("shdr_unterminated", line_no, fmt::format("multi-line block never closed by '{}'", multiline_end));
        out_.finish();
    }

private:
    std::set<std::string, std::less<>> scan_keys() {
        std::set<std::string, std::less<>> wanted, seen;
        for (const auto* list : {&map_.position, &map_.x, &map_.y, &map_.z, &map_.feed, &map_.spindle, &map_.block})
            wanted.insert(list->begin(), list->end());
        std::ifstream in(path_, std::ios::binary);
        if (!in) diag_.fail(0, "cannot open file");
        std::string line;
        while (std::getline(in, line)) {
            split_pipes(line, fields_);
            for (std::size_t i = 1; i < fields_.size(); i += 2)
                if (auto it = wanted.find(fields_[i]); it != wanted.end()) seen.insert(*it);
        }
        return seen;
    }

    void choose_keys(const std::set<std::string, std::less<>>& seen) {
        if (const auto* k = first_present(map_.position, seen)) {
            keys_.emplace(*k, Chan::Pos);
        } else {
            const std::pair<const std::vector<std::string>*, Chan> axes[] = {
                {&map_.x, Chan::AxisX}, {&map_.y, Chan::AxisY}, {&map_.z, Chan::AxisZ}};
            for (const auto& [list, ch] : axes) {
                const auto* k = first_present(*list, seen);
                if (!k)
                    diag_.fail(0, fmt::format("no position data: none of the path-position keys [{}] nor axis keys [{}] "
                                              "occur (give a --map file, see docs/formats.md)",
                                              fmt::join(map_.position, ", "), fmt::join(*list, ", ")));
                keys_.emplace(*k, ch);
            }
        }
        if (const auto* k = first_present(map_.feed, seen)) keys_.emplace(*k, Chan::Feed);
        if (const auto* k = first_present(map_.spindle, seen)) keys_.emplace(*k, Chan::Spindle);
        if (const auto* k = first_present(map_.block, seen)) keys_.emplace(*k, Chan::Block);
        try {
            length_mm_ = length_factor_mm(opt_.length_unit.value_or(map_.length_unit));
            feed_mm_min_ = feed_factor_mm_min(opt_.feed_unit.value_or(
                opt_.length_unit && !opt_.feed_unit ? *opt_.length_unit + "/s" : map_.feed_unit));
            spindle_rpm_ = speed_factor_rpm(map_.spindle_unit);
        } catch (const std::invalid_argument& e) {
            diag_.fail(0, e.what());
        }
    }

    void handle(std::string_view key, std::string_view value, double t_s, std::size_t line_no) {
        const auto it = keys_.find(key);
        if (it == keys_.end()) return;
        const Chan ch = it->second;
        if (value.empty() || value == "UNAVAILABLE") {
            diag_.warn("unavailable", line_no, fmt::format("key '{}' UNAVAILABLE or empty; value held", key));
            return;
        }
        Record r;
        r.t_s = t_s;
        r.line = line_no;
        r.ch = ch;
        if (ch == Chan::Block) {
            r.block = blocks_.intern(value);
            out_.push(r);
            return;
        }
        if (ch == Chan::Pos) {
            std::size_t start = 0;
            for (int k = 0; k < 3; ++k) {
                while (start < value.size() && value[start] == ' ') ++start;
                const std::size_t end = std::min(value.find(' ', start), value.size());
                r.v[k] = number(key, value.substr(start, end - start), line_no, "3 numbers 'x y z'") * length_mm_;
                start = end;
            }
            while (start < value.size() && value[start] == ' ') ++start;
            if (start != value.size())
                diag_.fail(line_no, fmt::format("key '{}': '{}' has more than 3 numbers (expected 'x y z')", key, value));
        } else {
            const double factor = ch == Chan::Feed ? feed_mm_min_ : ch == Chan::Spindle ? spindle_rpm_ : length_mm_;
            r.v[0] = number(key, value, line_no, "a number") * factor;
        }
        check_range(r, key);
        out_.push(r);
    }

    double number(std::string_view key, std::string_view text, std::size_t line_no, const char* expected) {
        double v = 0;
        const auto [p, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
        if (text.empty() || ec != std::errc() || p != text.data() + text.size())
            diag_.fail(line_no, fmt::format("key '{}': '{}' is not {}", key, text, expected));
        if (!std::isfinite(v)) diag_.fail(line_no, fmt::format("key '{}': '{}' is not a finite number", key, text));
        return v;
    }

    void check_range(const Record& r, std::string_view key) {
        if (r.ch == Chan::Feed && (r.v[0] < 0 || r.v[0] > limits_.max_feed_mm_min))
            diag_.warn("out_of_range", r.line, fmt::format("key '{}': feed {:.0f} mm/min outside 0..{} (declared unit "
                                                           "wrong? see --feed-units)", key, r.v[0], limits_.max_feed_mm_min));
        if (r.ch == Chan::Spindle && std::fabs(r.v[0]) > limits_.max_abs_spindle_rpm)
            diag_.warn("out_of_range", r.line, fmt::format("key '{}': spindle {:.0f} rpm beyond +-{}", key, r.v[0],
                                                           limits_.max_abs_spindle_rpm));
        if (r.ch != Chan::Feed && r.ch != Chan::Spindle)
            for (int k = 0; k < (r.ch == Chan::Pos ? 3 : 1); ++k)
                if (std::fabs(r.v[k]) > limits_.max_abs_position_mm)
                    diag_.warn("out_of_range", r.line, fmt::format("key '{}': position {:.3f} mm beyond +-{} mm", key, r.v[k],
                                                                   limits_.max_abs_position_mm));
    }

    const std::string& path_;
    const ReadOptions& opt_;
    Diagnostics& diag_;
    BlockTable& blocks_;
    RecordSink& out_;
    KeyMap map_;
    StageLimits limits_;
    std::map<std::string, Chan, std::less<>> keys_;
    std::vector<std::string_view> fields_;
    double length_mm_ = 1, feed_mm_min_ = 60, spindle_rpm_ = 1;
    bool have_origin_ = false;
    std::int64_t origin_sec_ = 0;
};

}  // namespace

void read_shdr(const std::string& path, const ReadOptions& opt, Diagnostics& diag, BlockTable& blocks, RecordSink& out) {
    ShdrReader(path, opt, diag, blocks, out).run();
}

Format detect_format(const std::string& path, Diagnostics& diag) {
    std::ifstream in(path, std::ios::binary);
    if (!in) diag.fail(0, "cannot open file");
    std::string line;
    while (std::getline(in, line)) {
        if (line.empty() || line.front() == '#' || line.front() == '*') continue;
        // An SHDR line starts with an ISO time stamp followed by '|'.
        const auto bar = line.find('|');
        if (bar != std::string::npos && parse_stamp(std::string_view(line).substr(0, bar))) return Format::Shdr;
        return Format::Csv;
    }
    diag.fail(0, "empty file: nothing to read");
}

}  // namespace cutload::motion_io::detail
