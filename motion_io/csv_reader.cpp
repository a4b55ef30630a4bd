// Stage "parse + validate" for CSV logs: one record at a time (textio::CsvReader: RFC 4180 quoting,
// decoded text, bounded memory), never the whole file. Which column feeds which channel comes from
// the channel map (built-in names, or a map file / preset for controller exports).
#include "channel_map.hpp"
#include "pipeline.hpp"

#include "textio/csv.hpp"
#include "textio/number.hpp"

#include <fmt/format.h>

#include <array>
#include <cmath>
#include <fstream>
#include <optional>

namespace cutload::motion_io::detail {
namespace {

using MC = MapChannel;

constexpr MC kRotary[3] = {MC::A, MC::B, MC::C};

std::string ascii_lower(std::string_view s) {
    std::string out(s);
    for (char& c : out)
        if (c >= 'A' && c <= 'Z') c = static_cast<char>(c - 'A' + 'a');
    return out;
}

std::string_view trim(std::string_view s) {
    while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
    while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
    return s;
}

struct Column {
    int index = -1;      // position in the row
    double factor = 1;   // to canonical unit
    std::string header;  // as written, for messages
    std::string unit;    // declared in the header ("x [in]"), empty when none
};

// A header cell: its name without the unit (lower case), the unit, the whole cell (lower case).
struct HeaderName {
    std::string name, unit, whole;
};

class CsvReader {
public:
    CsvReader(const std::string& path, const ReadOptions& opt, Diagnostics& diag, BlockTable& blocks, RecordSink& out)
        : path_(path), opt_(opt), diag_(diag), blocks_(blocks), out_(out), map_(load_channel_map(opt.map_file, Format::Csv)) {
        commanded_ = opt.positions == Positions::Commanded;
    }

    void run() {
        std::ifstream in(path_, std::ios::binary);
        if (!in) diag_.fail(0, "cannot open file");
        textio::CsvOptions o;
        o.delimiter = 0;   // detected on the header row, then fixed
        o.comment = '#';
        textio::CsvReader csv(in, diag_.file(), o);
        try {
            if (!csv.next()) diag_.fail(0, "empty file: expected a CSV header row with t, x, y, z");
            csv.set_delimiter(csv.delimiter());
            // A ';' or tab export writes decimal commas (0,125); a ',' export cannot.
            decimal_comma_ = csv.delimiter() != ',';
            parse_header(csv);
            while (csv.next()) parse_row(csv);
        } catch (const textio::TextError& e) {
            throw IngestError(e.what());
        }
        out_.finish();
    }

private:
    Column& col(MC c) { return cols_[static_cast<int>(c)]; }
    const Column& col(MC c) const { return cols_[static_cast<int>(c)]; }

    std::string candidates_text(MC c) const {
        std::string s = fmt::format("'{}'", fmt::join(map_[c], "', '"));
        return map_.origin.empty() ? s : s + " (" + map_.origin + ")";
    }

    HeaderName split_header(const textio::CsvReader& csv, std::size_t i) {
        HeaderName h;
        const std::string_view f = csv[i];
        h.whole = ascii_lower(f);
        const std::size_t lb = f.find('[');
        if (lb == std::string_view::npos) {
            h.name = h.whole;
            return h;
        }
        const std::size_t rb = f.find(']', lb);
        if (rb == std::string_view::npos)
            diag_.fail_at(csv.line_of(i), csv.column_of(i), fmt::format("column {} '{}': unclosed '[' in unit", i + 1, f));
        h.unit = std::string(trim(f.substr(lb + 1, rb - lb - 1)));
        h.name = ascii_lower(trim(f.substr(0, lb)));
        return h;
    }

    void parse_header(const textio::CsvReader& csv) {
        const std::size_t line_no = csv.line();
        n_fields_ = csv.size();
        std::vector<HeaderName> names;
        for (std::size_t i = 0; i < n_fields_; ++i) names.push_back(split_header(csv, i));
        // Per channel, the first candidate the header holds wins (a map may cover several exports).
        std::vector<int> claimed(n_fields_, -1);
        for (int c = 0; c < kMapChannels; ++c) {
            if (static_cast<MC>(c) == MC::Position) continue;
            for (const std::string& candidate : map_.candidates[c]) {
                const std::string want = ascii_lower(trim(candidate));
                std::vector<std::size_t> hits;
                for (std::size_t i = 0; i < n_fields_; ++i)
                    if (names[i].name == want || names[i].whole == want) hits.push_back(i);
                if (hits.empty()) continue;
                const std::size_t i = hits[0];
                if (hits.size() > 1)
                    diag_.fail(line_no, fmt::format("column {} '{}': channel '{}' appears twice (also column {})", hits[1] + 1,
                                                    csv[hits[1]], map_key(static_cast<MC>(c)), i + 1));
                if (claimed[i] >= 0)
                    diag_.fail(line_no, fmt::format("column {} '{}' matches both channel '{}' and channel '{}' (fix the map)",
                                                    i + 1, csv[i], map_key(static_cast<MC>(claimed[i])), map_key(static_cast<MC>(c))));
                claimed[i] = c;
                cols_[c] = Column{static_cast<int>(i), 1.0, std::string(csv[i]), names[i].unit};
                break;
            }
        }
        for (std::size_t i = 0; i < n_fields_; ++i)
            if (claimed[i] < 0)
                diag_.warn("unknown_column", line_no, fmt::format("column {} '{}' is not a known channel; ignored", i + 1, csv[i]));

        const std::array<MC, 3> actual{MC::X, MC::Y, MC::Z}, command{MC::XCmd, MC::YCmd, MC::ZCmd};
        auto present = [&](const std::array<MC, 3>& set) {
            return col(set[0]).index >= 0 && col(set[1]).index >= 0 && col(set[2]).index >= 0;
        };
        pos_ = commanded_ ? command : actual;
        other_ = commanded_ ? actual : command;
        for (MC c : pos_) {
            if (col(c).index >= 0) continue;
            if (commanded_)
                diag_.fail(line_no, fmt::format("no commanded position column for '{}' (none of {}): reading the commanded "
                                                "path from the log needs x_cmd, y_cmd, z_cmd or a map naming them",
                                                map_key(c), candidates_text(c)));
            diag_.fail(line_no, map_.origin.empty()
                                    ? fmt::format("missing required column '{}' (actual machine position; header needs t or "
                                                  "t_pos, x, y, z)", map_key(c))
                                    : fmt::format("missing required column for '{}': none of {}", map_key(c), candidates_text(c)));
        }
        diag_.facts().commanded_positions = present(command);
        other_present_ = present(other_);
        for (int k = 0; k < 3; ++k) diag_.facts().rotary[std::size_t(k)] = col(kRotary[k]).index >= 0;

        const bool has_time = col(MC::T).index >= 0 || col(MC::TPos).index >= 0;
        if (map_.sample_period_ms) {
            if (has_time)
                diag_.fail(line_no, fmt::format("column '{}' is a time column, but {} gives sample_period_ms, which is for "
                                                "exports without one",
                                                col(col(MC::T).index >= 0 ? MC::T : MC::TPos).header, map_.origin));
            row_period_s_ = *map_.sample_period_ms * 1e-3;
        } else if (!has_time) {
            diag_.fail(line_no, "missing required time column 't' (or per-channel 't_pos'); an export without a time "
                                "column needs a map with sample_period_ms (docs/formats.md)");
        }
        if (map_.sample_period_ms) {
            // Every channel is stamped by the row's place.
            time_of_pos_ = time_of_feed_ = time_of_spindle_ = time_of_block_ = MC::Count;
        } else {
            // Per-channel stamps replace t where present; without t, t_pos stands in for the others.
            const MC base = col(MC::T).index >= 0 ? MC::T : MC::TPos;
            time_of_pos_ = col(MC::TPos).index >= 0 ? MC::TPos : MC::T;
            time_of_feed_ = col(MC::TFeed).index >= 0 ? MC::TFeed : base;
            time_of_spindle_ = col(MC::TSpindle).index >= 0 ? MC::TSpindle : base;
            time_of_block_ = base;
        }
        for (int c = 0; c < kMapChannels; ++c)
            if (cols_[c].index >= 0) cols_[c].factor = unit_factor(static_cast<MC>(c), line_no);
        if (opt_.feed_unit && col(MC::Feed).index >= 0 && !col(MC::Feed).unit.empty())
            diag_.warn("feed_unit_override", line_no,
                       fmt::format("column '{}': declared unit overridden by --feed-units {}", col(MC::Feed).header, *opt_.feed_unit));
    }

    // The unit a column is read in: declared in its header, else the command line's, else the
    // map's, else the default. Two that disagree cannot both be right: an error, not a choice.
    std::string unit_of(const Column& c, const std::optional<std::string>& option, const char* option_name,
                        const std::optional<std::string>& mapped, const std::string& fallback, std::size_t line_no) {
        if (!c.unit.empty()) {
            if (option && normalise_unit(c.unit) != normalise_unit(*option))
                diag_.fail(line_no, fmt::format("column '{}' declares '{}' but {} {} was given", c.header, c.unit, option_name, *option));
            if (mapped && normalise_unit(c.unit) != normalise_unit(*mapped))
                diag_.fail(line_no, fmt::format("column '{}' declares '{}' but {} says '{}'", c.header, c.unit, map_.origin, *mapped));
            return c.unit;
        }
        return option ? *option : mapped ? *mapped : fallback;
    }

    double unit_factor(MC c, std::size_t line_no) {
        const Column& column = col(c);
        const std::optional<std::string> none;
        try {
            switch (c) {
                case MC::T: case MC::TPos: case MC::TFeed: case MC::TSpindle:
                    return time_factor_s(unit_of(column, none, "", map_.time_unit, "s", line_no));
                case MC::X: case MC::Y: case MC::Z: case MC::XCmd: case MC::YCmd: case MC::ZCmd:
                    return length_factor_mm(unit_of(column, opt_.length_unit, "--units", map_.length_unit, "mm", line_no));
                case MC::A: case MC::B: case MC::C:
                    return angle_factor_deg(unit_of(column, none, "", map_.angle_unit, "deg", line_no));
                case MC::Feed: {
                    if (opt_.feed_unit) return feed_factor_mm_min(*opt_.feed_unit);
                    const std::string length = opt_.length_unit.value_or(map_.length_unit.value_or("mm"));
                    const std::string u = unit_of(column, none, "", map_.feed_unit, length + "/min", line_no);
                    if (!column.unit.empty() && opt_.length_unit) {
                        const std::string declared_length = normalise_unit(u).substr(0, normalise_unit(u).find('/'));
                        if (declared_length != normalise_unit(*opt_.length_unit))
                            diag_.fail(line_no, fmt::format("column '{}' declares '{}' but --units {} was given", column.header,
                                                            column.unit, *opt_.length_unit));
                    }
                    return feed_factor_mm_min(u);
                }
                case MC::Spindle:
                    return speed_factor_rpm(unit_of(column, none, "", map_.spindle_unit, "rpm", line_no));
                default:
                    return 1.0;
            }
        } catch (const std::invalid_argument& e) {
            diag_.fail(line_no, fmt::format("column '{}': {}", column.header, e.what()));
        }
    }

    std::optional<double> number(MC c, const textio::CsvReader& csv) {
        const int idx = col(c).index;
        if (idx < 0) return std::nullopt;
        const auto i = static_cast<std::size_t>(idx);
        const std::string_view f = csv[i];
        const textio::ParsedNumber p = textio::parse_number(f, decimal_comma_);
        if (p.error == textio::NumberError::empty) return std::nullopt;
        if (!p)
            diag_.fail_at(csv.line_of(i), csv.column_of(i),
                          fmt::format("column '{}': {}", col(c).header, textio::number_problem(f, p.error)));
        return p.value * col(c).factor;
    }

    double time_of(MC c, const textio::CsvReader& csv) {
        if (c == MC::Count) return row_time_s_;
        const auto t = number(c, csv);
        if (!t) diag_.fail(csv.line(), fmt::format("column '{}': empty time stamp", col(c).header));
        return *t;
    }

    // A block value: text as written, or with a map's block_prefix a number named prefix + integer
    // (controller exports write the sequence number as 1.40E+01).
    std::int32_t block_id(const textio::CsvReader& csv, std::size_t i) {
        const std::string_view b = csv[i];
        if (!map_.block_prefix) return blocks_.intern(b);
        const textio::ParsedNumber p = textio::parse_number(b, decimal_comma_);
        if (!p || std::fabs(p.value) > 1e15 || p.value != std::round(p.value))
            diag_.fail_at(csv.line_of(i), csv.column_of(i),
                          fmt::format("column '{}': '{}' is not a whole block number ({} gives block_prefix)", col(MC::Block).header,
                                      b, map_.origin));
        return blocks_.intern(*map_.block_prefix + std::to_string(static_cast<long long>(p.value)));
    }

    void parse_row(const textio::CsvReader& csv) {
        const std::size_t line_no = csv.line();
        if (csv.size() != n_fields_)
            diag_.fail(line_no, fmt::format("expected {} fields as in the header, found {}", n_fields_, csv.size()));
        row_time_s_ = static_cast<double>(rows_++) * row_period_s_;
        // The row's readings go downstream in time order (per-channel stamps differ within a row).
        row_records_.clear();
        Record r;
        r.line = line_no;
        std::array<std::optional<double>, 3> p, rot;
        for (int k = 0; k < 3; ++k) p[k] = number(pos_[k], csv);
        for (int k = 0; k < 3; ++k) rot[k] = number(kRotary[k], csv);
        if (p[0] || p[1] || p[2]) {
            if (!(p[0] && p[1] && p[2]))
                diag_.fail(line_no, fmt::format("column '{}': empty while other axes are present",
                                                col(pos_[!p[0] ? 0 : !p[1] ? 1 : 2]).header));
            r.t_s = time_of(time_of_pos_, csv);
            r.ch = Chan::Pos;
            for (int k = 0; k < 3; ++k) {
                r.v[k] = *p[k];
                const auto i = static_cast<std::size_t>(col(pos_[k]).index);
                diag_.facts().resolution.add(k, textio::trim_blanks(csv[i]), col(pos_[k]).factor);
                if (std::fabs(r.v[k]) > limits_.max_abs_position_mm)
                    diag_.warn("out_of_range", line_no, fmt::format("position {:.10g} mm beyond +-{} mm", r.v[k],
                                                                    limits_.max_abs_position_mm));
            }
            // One latch shows every axis: a rotary column of the log is part of each position reading.
            for (int k = 0; k < 3; ++k) {
                if (col(kRotary[k]).index < 0) continue;
                if (!rot[k])
                    diag_.fail(line_no, fmt::format("column '{}': empty while the linear axes are present",
                                                    col(kRotary[k]).header));
                if (!(std::fabs(*rot[k]) <= kMaxAbsRotaryDeg))   // NaN too
                    diag_.fail(line_no, fmt::format("column '{}': {:.10g} deg beyond +-{:g} deg", col(kRotary[k]).header,
                                                    *rot[k], kMaxAbsRotaryDeg));
                r.rot_deg[k] = *rot[k];
            }
            row_records_.push_back(r);
        } else {
            for (int k = 0; k < 3; ++k)
                if (rot[k])
                    diag_.fail(line_no, fmt::format("column '{}': a rotary position without the linear axes x, y, z",
                                                    col(kRotary[k]).header));
        }
        // Validated, not used here: the other position set.
        if (other_present_)
            for (MC c : other_) (void)number(c, csv);
        if (const auto f = number(MC::Feed, csv)) {
            Record fr{time_of(time_of_feed_, csv), line_no, Chan::Feed, {*f, 0, 0}, -1};
            if (*f < 0 || *f > limits_.max_feed_mm_min)
                diag_.warn("out_of_range", line_no, fmt::format("feed {:.10g} mm/min outside 0..{}", *f, limits_.max_feed_mm_min));
            row_records_.push_back(fr);
        }
        if (const auto s = number(MC::Spindle, csv)) {
            Record sr{time_of(time_of_spindle_, csv), line_no, Chan::Spindle, {*s, 0, 0}, -1};
            if (std::fabs(*s) > limits_.max_abs_spindle_rpm)
                diag_.warn("out_of_range", line_no, fmt::format("spindle {:.10g} rpm beyond +-{}", *s, limits_.max_abs_spindle_rpm));
            row_records_.push_back(sr);
        }
        if (col(MC::Block).index >= 0) {
            const auto i = static_cast<std::size_t>(col(MC::Block).index);
            if (!csv[i].empty()) {
                Record br{time_of(time_of_block_, csv), line_no, Chan::Block, {0, 0, 0}, block_id(csv, i)};
                row_records_.push_back(br);
            }
        }
        if (const auto tool = number(MC::Tool, csv)) {
            if (*tool < 0 || *tool > 99999999 || *tool != std::floor(*tool))
                diag_.fail(line_no, fmt::format("column '{}': '{}' is not a tool number (a whole number from 0)", col(MC::Tool).header,
                                                textio::printable(csv[static_cast<std::size_t>(col(MC::Tool).index)])));
            Record tr{time_of(time_of_block_, csv), line_no, Chan::Tool, {*tool, 0, 0}, -1};
            row_records_.push_back(tr);
        }
        // At most five records: an insertion sort keeps equal stamps in column order.
        for (std::size_t i = 1; i < row_records_.size(); ++i)
            for (std::size_t j = i; j > 0 && row_records_[j].t_s < row_records_[j - 1].t_s; --j)
                std::swap(row_records_[j], row_records_[j - 1]);
        for (const Record& rec : row_records_) out_.push(rec);
    }

    const std::string& path_;
    const ReadOptions& opt_;
    Diagnostics& diag_;
    BlockTable& blocks_;
    RecordSink& out_;
    ChannelMap map_;
    StageLimits limits_;
    bool commanded_ = false, other_present_ = false, decimal_comma_ = false;
    std::array<MC, 3> pos_{MC::X, MC::Y, MC::Z}, other_{MC::XCmd, MC::YCmd, MC::ZCmd};
    std::array<Column, kMapChannels> cols_{};
    std::vector<Record> row_records_;
    std::size_t n_fields_ = 0, rows_ = 0;
    double row_period_s_ = 0, row_time_s_ = 0;
    MC time_of_pos_ = MC::T, time_of_feed_ = MC::T, time_of_spindle_ = MC::T, time_of_block_ = MC::T;
};

}  // namespace

void read_csv(const std::string& path, const ReadOptions& opt, Diagnostics& diag, BlockTable& blocks, RecordSink& out) {
    CsvReader(path, opt, diag, blocks, out).run();
}

}  // namespace cutload::motion_io::detail
