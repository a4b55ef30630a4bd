// Stage "parse + validate" for MTConnect SHDR streams (adapter output):
//   timestamp|key|value|key|value...         samples and events
//   timestamp|key|LEVEL|code|qualifier|severity|text   conditions (skipped)
//   timestamp|@ASSET@|id|type|--multiline--XXXX ... --multiline--XXXX   assets (skipped)
//   * command: value                        agent commands (skipped)
// Which data items feed which channel comes from the channel map (built-in defaults, a JSON file
// or a preset; docs/formats.md). A first pass collects only the key names present, so the
// highest-priority candidate that the log actually contains is chosen; both passes stream line by
// line, each line bounded and decoded to UTF-8 (textio), so a Latin-1 block name reads as what it
// means.
//
// Rotary items (A, B, C in degrees). The ingest must know which rotary axes the position readings
// carry before the first record (ReaderFacts::rotary: the unwrap and resample stages are set up
// for them), while an SHDR stream names its items only as they change. The first pass settles it:
// it reads the whole file anyway, so a rotary axis counts as present when one of its candidate
// keys carries a value somewhere in the file (a key that only ever says UNAVAILABLE gives no
// position and does not make the axis present, so a later candidate with values can serve). The
// rotary items are then latched into the position readings like single linear axes (stage
// sequence), with a 3-D path position or with single axes alike.
#include "channel_map.hpp"
#include "pipeline.hpp"
#include "motion_io/shdr.hpp"

#include "textio/lines.hpp"
#include "textio/number.hpp"

#include <fmt/format.h>

#include <charconv>
#include <cmath>
#include <fstream>
#include <set>

namespace cutload::motion_io::detail {
namespace {

// The line tokenizer and the time stamp parser live in shdr_line.cpp (public in
// motion_io/shdr.hpp) so the live sources read lines exactly as this reader does.

const std::string* first_present(const std::vector<std::string>& candidates, const std::set<std::string, std::less<>>& seen) {
    for (const auto& k : candidates)
        if (seen.count(k)) return &k;
    return nullptr;
}

// A value that is a reading: not UNAVAILABLE, not empty (such a value is held, see handle()).
bool rotary_value(std::string_view value) { return !value.empty() && value != "UNAVAILABLE"; }

// Character column of a field that is a view into `line`.
std::size_t column_in(std::string_view line, std::string_view field) {
    return textio::characters(line.substr(0, static_cast<std::size_t>(field.data() - line.data()))) + 1;
}

class ShdrReader {
public:
    ShdrReader(const std::string& path, const ReadOptions& opt, Diagnostics& diag, BlockTable& blocks, RecordSink& out)
        : path_(path), opt_(opt), diag_(diag), blocks_(blocks), out_(out), map_(load_channel_map(opt.map_file, Format::Shdr)) {}

    void run() {
        choose_keys(scan_keys());
        std::ifstream in(path_, std::ios::binary);
        if (!in) diag_.fail(0, "cannot open file");
        try {
            read(in);
        } catch (const textio::TextError& e) {
            throw IngestError(e.what());
        }
        out_.finish();
    }

private:
    void read(std::istream& in) {
        textio::LineReader lines(in, diag_.file());
        ShdrLineTokenizer tokens;
        std::size_t line_no = 0;
        while (lines.next()) {
            line_no = lines.number();
            // Inside a multi-line (asset) body only the terminator matters: the body is not decoded.
            line_ = tokens.in_multiline() ? lines.raw() : lines.text();
            const ShdrLineKind kind = tokens.next(line_);
            if (kind == ShdrLineKind::Short)
                diag_.warn("shdr_short_line", line_no, "line without 'timestamp|key|value'; skipped");
            if (kind != ShdrLineKind::Data) continue;
            const auto& fields = tokens.fields();
            const auto stamp = parse_iso_time(fields[0]);
            if (!stamp)
                diag_.fail_at(line_no, 1, fmt::format("'{}' is not an ISO 8601 time stamp (expected e.g. 2022-08-08T13:51:34.7167146Z)",
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
    }

    std::set<std::string, std::less<>> scan_keys() {
        std::set<std::string, std::less<>> wanted, seen, rotary;
        for (const auto& list : map_.candidates) wanted.insert(list.begin(), list.end());
        for (const MapChannel c : {MapChannel::A, MapChannel::B, MapChannel::C}) rotary.insert(map_[c].begin(), map_[c].end());
        std::ifstream in(path_, std::ios::binary);
        if (!in) diag_.fail(0, "cannot open file");
        try {
            textio::LineReader lines(in, diag_.file());
            std::string decoded;
            while (lines.next()) {
                std::string_view line = lines.raw();
                if (!textio::is_ascii(line)) {
                    // Keys are matched as text; a line that is not text is reported by the main pass if it matters.
                    decoded.clear();
                    if (textio::append_utf8(decoded, line)) continue;
                    line = decoded;
                }
                split_shdr_fields(line, fields_);
                for (std::size_t i = 1; i < fields_.size(); i += 2)
                    if (auto it = wanted.find(fields_[i]); it != wanted.end()) {
                        // A rotary key counts once it carries a value (see the top of this file).
                        const std::string_view value = i + 1 < fields_.size() ? fields_[i + 1] : std::string_view();
                        if (rotary.count(*it) && !rotary_value(value)) continue;
                        seen.insert(*it);
                    }
            }
        } catch (const textio::TextError& e) {
            throw IngestError(e.what());
        }
        return seen;
    }

    void choose_keys(const std::set<std::string, std::less<>>& seen) {
        using MC = MapChannel;
        const bool commanded = opt_.positions == Positions::Commanded;
        const std::pair<MC, Chan> actual[] = {{MC::X, Chan::AxisX}, {MC::Y, Chan::AxisY}, {MC::Z, Chan::AxisZ}};
        const std::pair<MC, Chan> command[] = {{MC::XCmd, Chan::AxisX}, {MC::YCmd, Chan::AxisY}, {MC::ZCmd, Chan::AxisZ}};
        bool all_commands = true;
        for (const auto& [c, ch] : command) all_commands = all_commands && first_present(map_[c], seen);
        diag_.facts().commanded_positions = all_commands;
        auto axis_keys = [&](const std::pair<MC, Chan> (&set)[3], const char* missing) {
            for (const auto& [c, ch] : set) {
                const auto* k = first_present(map_[c], seen);
                if (!k) diag_.fail(0, fmt::format(fmt::runtime(missing), fmt::join(map_[MC::Position], ", "), fmt::join(map_[c], ", "), map_key(c)));
                keys_.emplace(*k, ch);
                axis_of_key_.emplace(*k, static_cast<int>(ch) - static_cast<int>(Chan::AxisX));
            }
        };
        if (commanded) {
            axis_keys(command, "no commanded position data: none of the keys [{1}] occur (give a --map file naming {2}, "
                               "see docs/formats.md)");
        } else if (const auto* k = first_present(map_[MC::Position], seen)) {
            keys_.emplace(*k, Chan::Pos);
        } else {
            axis_keys(actual, "no position data: none of the path-position keys [{0}] nor axis keys [{1}] occur (give a "
                              "--map file, see docs/formats.md)");
        }
        const std::pair<MC, Chan> rotary[] = {{MC::A, Chan::AxisA}, {MC::B, Chan::AxisB}, {MC::C, Chan::AxisC}};
        for (std::size_t k = 0; k < 3; ++k)
            if (const auto* key = first_present(map_[rotary[k].first], seen)) {
                // One item cannot be two axes: a map that says so is refused, not read one way.
                if (!keys_.emplace(*key, rotary[k].second).second)
                    diag_.fail(0, fmt::format("key '{}' is named for channel '{}' and for another channel (fix the map)",
                                              *key, map_key(rotary[k].first)));
                diag_.facts().rotary[k] = true;
                diag_.facts().rotary_items = true;
            }
        if (const auto* k = first_present(map_[MC::Feed], seen)) keys_.emplace(*k, Chan::Feed);
        if (const auto* k = first_present(map_[MC::Spindle], seen)) keys_.emplace(*k, Chan::Spindle);
        if (const auto* k = first_present(map_[MC::Block], seen)) keys_.emplace(*k, Chan::Block);
        try {
            const ShdrUnitFactors f = shdr_unit_factors(shdr_key_map(map_), opt_);
            length_mm_ = f.length_mm, feed_mm_min_ = f.feed_mm_min, spindle_rpm_ = f.spindle_rpm;
            // MTConnect declares ANGLE items in degrees; a map may say otherwise.
            angle_deg_ = angle_factor_deg(map_.angle_unit.value_or("deg"));
        } catch (const std::invalid_argument& e) {
            diag_.fail(0, map_.origin.empty() ? std::string(e.what()) : map_.origin + ": " + e.what());
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
            r.block = block_id(key, value, line_no);
            out_.push(r);
            return;
        }
        if (ch == Chan::Pos) {
            std::size_t start = 0;
            for (int k = 0; k < 3; ++k) {
                while (start < value.size() && value[start] == ' ') ++start;
                const std::size_t end = std::min(value.find(' ', start), value.size());
                const std::string_view text = value.substr(start, end - start);
                r.v[k] = number(key, text, line_no, "3 numbers 'x y z'") * length_mm_;
                diag_.facts().resolution.add(k, text, length_mm_);
                start = end;
            }
            while (start < value.size() && value[start] == ' ') ++start;
            if (start != value.size())
                diag_.fail_at(line_no, column_in(line_, value),
                              fmt::format("key '{}': '{}' has more than 3 numbers (expected 'x y z')", key, value));
        } else if (is_rotary_axis(ch)) {
            r.v[0] = number(key, value, line_no, "a number") * angle_deg_;
            if (!(std::fabs(r.v[0]) <= kMaxAbsRotaryDeg))
                diag_.fail_at(line_no, column_in(line_, value),
                              fmt::format("key '{}': {:.10g} deg beyond +-{:g} deg: no axis position (a counter that "
                                          "overflowed, or a key that is not this axis's angle)",
                                          key, r.v[0], kMaxAbsRotaryDeg));
            out_.push(r);
            return;
        } else {
            const double factor = ch == Chan::Feed ? feed_mm_min_ : ch == Chan::Spindle ? spindle_rpm_ : length_mm_;
            r.v[0] = number(key, value, line_no, "a number") * factor;
            if (const auto axis = axis_of_key_.find(key); axis != axis_of_key_.end())
                diag_.facts().resolution.add(axis->second, textio::trim_blanks(value), length_mm_);
        }
        check_range(r, key);
        out_.push(r);
    }

    // A block value: text as written, or with a map's block_prefix a number named prefix + integer.
    std::int32_t block_id(std::string_view key, std::string_view value, std::size_t line_no) {
        if (!map_.block_prefix) return blocks_.intern(value);
        const textio::ParsedNumber p = textio::parse_number(value);
        if (!p || std::fabs(p.value) > 1e15 || p.value != std::round(p.value))
            diag_.fail_at(line_no, column_in(line_, value),
                          fmt::format("key '{}': '{}' is not a whole block number ({} gives block_prefix)", key, value, map_.origin));
        return blocks_.intern(*map_.block_prefix + std::to_string(static_cast<long long>(p.value)));
    }

    double number(std::string_view key, std::string_view text, std::size_t line_no, const char* expected) {
        const textio::ParsedNumber p = textio::parse_number(text);
        if (p) return p.value;
        const std::size_t column = column_in(line_, text);
        if (p.error == textio::NumberError::not_finite)
            diag_.fail_at(line_no, column, fmt::format("key '{}': '{}' is not a finite number", key, text));
        if (p.error == textio::NumberError::digit_group)
            diag_.fail_at(line_no, column, fmt::format("key '{}': {}", key, textio::number_problem(text, p.error)));
        diag_.fail_at(line_no, column, fmt::format("key '{}': '{}' is not {}", key, text, expected));
    }

    void check_range(const Record& r, std::string_view key) {
        if (r.ch == Chan::Feed && (r.v[0] < 0 || r.v[0] > limits_.max_feed_mm_min))
            diag_.warn("out_of_range", r.line, fmt::format("key '{}': feed {:.10g} mm/min outside 0..{} (declared unit "
                                                           "wrong? see --feed-units)", key, r.v[0], limits_.max_feed_mm_min));
        if (r.ch == Chan::Spindle && std::fabs(r.v[0]) > limits_.max_abs_spindle_rpm)
            diag_.warn("out_of_range", r.line, fmt::format("key '{}': spindle {:.10g} rpm beyond +-{}", key, r.v[0],
                                                           limits_.max_abs_spindle_rpm));
        if (r.ch != Chan::Feed && r.ch != Chan::Spindle)
            for (int k = 0; k < (r.ch == Chan::Pos ? 3 : 1); ++k)
                if (std::fabs(r.v[k]) > limits_.max_abs_position_mm)
                    diag_.warn("out_of_range", r.line, fmt::format("key '{}': position {:.10g} mm beyond +-{} mm", key, r.v[k],
                                                                   limits_.max_abs_position_mm));
    }

    const std::string& path_;
    const ReadOptions& opt_;
    Diagnostics& diag_;
    BlockTable& blocks_;
    RecordSink& out_;
    ChannelMap map_;
    StageLimits limits_;
    std::map<std::string, Chan, std::less<>> keys_;
    std::map<std::string, int, std::less<>> axis_of_key_;
    std::vector<std::string_view> fields_;
    std::string_view line_;
    double length_mm_ = 1, feed_mm_min_ = 60, spindle_rpm_ = 1, angle_deg_ = 1;
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
    try {
        textio::LineReader lines(in, diag.file());
        while (lines.next()) {
            const std::string_view line = lines.raw();
            if (line.empty() || line.front() == '#' || line.front() == '*') continue;
            // An SHDR line starts with an ISO time stamp followed by '|'.
            const auto bar = line.find('|');
            if (bar != std::string_view::npos && parse_iso_time(line.substr(0, bar))) return Format::Shdr;
            return Format::Csv;
        }
    } catch (const textio::TextError& e) {
        throw IngestError(e.what());
    }
    diag.fail(0, "empty file: nothing to read");
}

}  // namespace cutload::motion_io::detail
