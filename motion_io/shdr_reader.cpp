// Stage "parse + validate" for MTConnect SHDR streams (adapter output):
//   timestamp|key|value|key|value...         samples and events
//   timestamp|key|LEVEL|code|qualifier|severity|text   conditions (skipped)
//   timestamp|@ASSET@|id|type|--multiline--XXXX ... --multiline--XXXX   assets (skipped)
//   * command: value                        agent commands (skipped)
// Which data items feed which channel comes from a key map (built-in defaults or a JSON file,
// docs/formats.md). A first pass collects only the key names present, so the highest-priority
// candidate that the log actually contains is chosen; both passes stream line by line.
#include "pipeline.hpp"
#include "motion_io/shdr.hpp"

#include <fmt/format.h>

#include <charconv>
#include <cmath>
#include <fstream>
#include <set>

namespace cutload::motion_io::detail {
namespace {

// The key map, the line tokenizer and the time stamp parser live in shdr_keys.cpp / shdr_line.cpp
// (public in motion_io/shdr.hpp) so the live sources read lines exactly as this reader does.
using KeyMap = ShdrKeyMap;

const std::string* first_present(const std::vector<std::string>& candidates, const std::set<std::string, std::less<>>& seen) {
    for (const auto& k : candidates)
        if (seen.count(k)) return &k;
    return nullptr;
}

class ShdrReader {
public:
    ShdrReader(const std::string& path, const ReadOptions& opt, Diagnostics& diag, BlockTable& blocks, RecordSink& out)
        : path_(path), opt_(opt), diag_(diag), blocks_(blocks), out_(out), map_(load_shdr_key_map(opt.map_file)) {}

    void run() {
        choose_keys(scan_keys());
        std::ifstream in(path_, std::ios::binary);
        if (!in) diag_.fail(0, "cannot open file");
        std::string line;
        std::size_t line_no = 0;
        ShdrLineTokenizer tokens;
        while (std::getline(in, line)) {
            ++line_no;
            const ShdrLineKind kind = tokens.next(line);
            if (kind == ShdrLineKind::Short)
                diag_.warn("shdr_short_line", line_no, "line without 'timestamp|key|value'; skipped");
            if (kind != ShdrLineKind::Data) continue;
            const auto& fields = tokens.fields();
            const auto stamp = parse_iso_time(fields[0]);
            if (!stamp)
                diag_.fail(line_no, fmt::format("'{}' is not an ISO 8601 time stamp (expected e.g. 2022-08-08T13:51:34.7167146Z)",
                                                fields[0]));
            if (!have_origin_) {
                origin_sec_ = stamp->sec;
                have_origin_ = true;
            }
            const double t_s = static_cast<double>(stamp->sec - origin_sec_) + stamp->frac;
            if (tokens.odd_fields())
                diag_.warn("shdr_odd_fields", line_no, "odd number of key/value fields; the last one ignored");
            for (std::size_t i = 1; i + 1 < fields.size(); i += 2) handle(fields[i], fields[i + 1], t_s, line_no);
        }
        if (tokens.in_multiline())
            diag_.warn("shdr_unterminated", line_no,
                       fmt::format("multi-line block never closed by '{}'", tokens.multiline_terminator()));
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
            split_shdr_fields(line, fields_);
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
            const ShdrUnitFactors f = shdr_unit_factors(map_, opt_);
            length_mm_ = f.length_mm, feed_mm_min_ = f.feed_mm_min, spindle_rpm_ = f.spindle_rpm;
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
        if (bar != std::string::npos && parse_iso_time(std::string_view(line).substr(0, bar))) return Format::Shdr;
        return Format::Csv;
    }
    diag.fail(0, "empty file: nothing to read");
}

}  // namespace cutload::motion_io::detail
