// Stage "parse + validate" for CSV logs: one line at a time, never the whole file.
#include "pipeline.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <fstream>
#include <optional>

namespace cutload::motion_io::detail {
namespace {

enum Col { kT, kTPos, kTFeed, kTSpindle, kX, kY, kZ, kA, kB, kC, kFeed, kSpindle, kBlock, kTool, kNumCols };
constexpr std::array<const char*, kNumCols> kColNames{"t", "t_pos", "t_feed", "t_spindle", "x", "y", "z",
                                                      "a", "b", "c", "feed", "spindle", "block", "tool"};

std::string_view trim(std::string_view s) {
    while (!s.empty() && std::isspace(static_cast<unsigned char>(s.front()))) s.remove_prefix(1);
    while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.remove_suffix(1);
    return s;
}

// Splits on commas; a field wrapped in double quotes may contain commas (block text).
void split_fields(std::string_view line, std::vector<std::string_view>& out) {
    out.clear();
    std::size_t i = 0;
    while (true) {
        while (i < line.size() && line[i] == ' ') ++i;
        if (i < line.size() && line[i] == '"') {
            const std::size_t close = line.find('"', i + 1);
            const std::size_t end = close == std::string_view::npos ? line.size() : close;
            out.push_back(line.substr(i + 1, end - i - 1));
            const std::size_t comma = line.find(',', end);
            if (comma == std::string_view::npos) return;
            i = comma + 1;
            continue;
        }
        const std::size_t comma = line.find(',', i);
        if (comma == std::string_view::npos) {
            out.push_back(trim(line.substr(i)));
            return;
        }
        out.push_back(trim(line.substr(i, comma - i)));
        i = comma + 1;
    }
}

struct Column {
    int index = -1;      // position in the row
    double factor = 1;   // to canonical unit
    std::string header;  // as written, for messages
};

class CsvReader {
public:
    CsvReader(const std::string& path, const ReadOptions& opt, Diagnostics& diag, BlockTable& blocks, RecordSink& out)
        : path_(path), opt_(opt), diag_(diag), blocks_(blocks), out_(out) {}

    void run() {
        std::ifstream in(path_, std::ios::binary);
        if (!in) diag_.fail(0, "cannot open file");
        std::vector<char> buffer(1 << 20);
        in.rdbuf()->pubsetbuf(buffer.data(), static_cast<std::streamsize>(buffer.size()));
        std::string line;
        std::size_t line_no = 0;
        bool have_header = false;
        while (std::getline(in, line)) {
            ++line_no;
            if (!line.empty() && line.back() == '\r') line.pop_back();
            const std::string_view sv = trim(line);
            if (sv.empty() || sv.front() == '#') continue;
            if (!have_header) {
                parse_header(sv, line_no);
                have_header = true;
                continue;
            }
            parse_row(sv, line_no);
        }
        if (!have_header) diag_.fail(0, "empty file: expected a CSV header row with t, x, y, z");
        out_.finish();
    }

private:
    void parse_header(std::string_view header, std::size_t line_no) {
        split_fields(header, fields_);
        n_fields_ = fields_.size();
        for (std::size_t i = 0; i < fields_.size(); ++i) {
            std::string name, unit;
            const std::string_view f = fields_[i];
            const std::size_t lb = f.find('[');
            if (lb != std::string_view::npos) {
                const std::size_t rb = f.find(']', lb);
                if (rb == std::string_view::npos)
                    diag_.fail(line_no, fmt::format("column {} '{}': unclosed '[' in unit", i + 1, f));
                unit = std::string(trim(f.substr(lb + 1, rb - lb - 1)));
                name = std::string(trim(f.substr(0, lb)));
            } else {
                name = std::string(f);
            }
            std::transform(name.begin(), name.end(), name.begin(), [](unsigned char c) { return std::tolower(c); });
            const auto it = std::find(kColNames.begin(), kColNames.end(), name);
            if (it == kColNames.end()) {
                diag_.warn("unknown_column", line_no, fmt::format("column {} '{}' is not a known channel; ignored", i + 1, f));
                continue;
            }
            const int c = static_cast<int>(it - kColNames.begin());
            if (cols_[c].index >= 0)
                diag_.fail(line_no, fmt::format("column {} '{}': channel '{}' appears twice", i + 1, f, name));
            cols_[c].index = static_cast<int>(i);
            cols_[c].header = std::string(f);
            cols_[c].factor = unit_factor(c, unit, line_no, f);
        }
        for (int c : {kX, kY, kZ})
            if (cols_[c].index < 0)
                diag_.fail(line_no, fmt::format("missing required column '{}' (actual machine position; header needs "
                                                "t or t_pos, x, y, z)", kColNames[c]));
        if (cols_[kT].index < 0 && cols_[kTPos].index < 0)
            diag_.fail(line_no, "missing required time column 't' (or per-channel 't_pos')");
        // Per-channel stamps replace t where present; without t, t_pos stands in for the others.
        const int base = cols_[kT].index >= 0 ? kT : kTPos;
        time_of_pos_ = cols_[kTPos].index >= 0 ? kTPos : kT;
        time_of_feed_ = cols_[kTFeed].index >= 0 ? kTFeed : base;
        time_of_spindle_ = cols_[kTSpindle].index >= 0 ? kTSpindle : base;
        time_of_block_ = base;
        if (opt_.feed_unit && cols_[kFeed].index >= 0 && fields_[cols_[kFeed].index].find('[') != std::string_view::npos)
            diag_.warn("feed_unit_override", line_no,
                       fmt::format("column '{}': declared unit overridden by --feed-units {}", cols_[kFeed].header,
                                   *opt_.feed_unit));
    }

    double unit_factor(int c, const std::string& declared, std::size_t line_no, std::string_view header) {
        try {
            switch (c) {
                case kT: case kTPos: case kTFeed: case kTSpindle:
                    return time_factor_s(declared.empty() ? "s" : declared);
                case kX: case kY: case kZ:
                    return length_factor_mm(length_unit(declared, line_no, header));
                case kA: case kB: case kC:
                    return angle_factor_deg(declared.empty() ? "deg" : declared);
                case kFeed:
                    if (opt_.feed_unit) return feed_factor_mm_min(*opt_.feed_unit);
                    if (!declared.empty()) {
                        const std::string u = normalise_unit(declared);
                        (void)length_unit(u.substr(0, u.find('/')), line_no, header);
                        return feed_factor_mm_min(u);
                    }
                    return feed_factor_mm_min(length_unit("", line_no, header) + "/min");
                case kSpindle:
                    return speed_factor_rpm(declared.empty() ? "rpm" : declared);
                default:
                    return 1.0;
            }
        } catch (const std::invalid_argument& e) {
            diag_.fail(line_no, fmt::format("column '{}': {}", header, e.what()));
        }
    }

    // --units fills in where the log is silent; where the log declares a different unit the two
    // cannot both be right, so that is an error rather than a silent choice.
    std::string length_unit(const std::string& declared, std::size_t line_no, std::string_view header) {
        if (declared.empty()) return opt_.length_unit.value_or("mm");
        if (opt_.length_unit && normalise_unit(declared) != normalise_unit(*opt_.length_unit))
            diag_.fail(line_no, fmt::format("column '{}' declares '{}' but --units {} was given", header, declared,
                                            *opt_.length_unit));
        return declared;
    }

    std::optional<double> number(int c, std::size_t line_no) {
        const int idx = cols_[c].index;
        if (idx < 0) return std::nullopt;
        const std::string_view f = fields_[static_cast<std::size_t>(idx)];
        if (f.empty()) return std::nullopt;
        double v = 0;
        const char* first = f.data();
        if (*first == '+') ++first;
        const auto [ptr, ec] = std::from_chars(first, f.data() + f.size(), v);
        if (ec != std::errc() || ptr != f.data() + f.size())
            diag_.fail(line_no, fmt::format("column '{}': '{}' is not a number", cols_[c].header, f));
        if (!std::isfinite(v))
            diag_.fail(line_no, fmt::format("column '{}': '{}' is not a finite number", cols_[c].header, f));
        return v * cols_[c].factor;
    }

    double time_of(int c, std::size_t line_no) {
        const auto t = number(c, line_no);
        if (!t) diag_.fail(line_no, fmt::format("column '{}': empty time stamp", cols_[c].header));
        return *t;
    }

    void parse_row(std::string_view row, std::size_t line_no) {
        split_fields(row, fields_);
        if (fields_.size() != n_fields_)
            diag_.fail(line_no, fmt::format("expected {} fields as in the header, found {}", n_fields_, fields_.size()));
        // The row's readings go downstream in time order (per-channel stamps differ within a row).
        row_records_.clear();
        Record r;
        r.line = line_no;
        const auto x = number(kX, line_no), y = number(kY, line_no), z = number(kZ, line_no);
        if (x || y || z) {
            if (!(x && y && z))
                diag_.fail(line_no, fmt::format("column '{}': empty while other axes are present",
                                                cols_[!x ? kX : !y ? kY : kZ].header));
            r.t_s = time_of(time_of_pos_, line_no);
            r.ch = Chan::Pos;
            r.v[0] = *x, r.v[1] = *y, r.v[2] = *z;
            for (double p : r.v)
                if (std::fabs(p) > limits_.max_abs_position_mm)
                    diag_.warn("out_of_range", line_no, fmt::format("position {:.3f} mm beyond +-{} mm", p,
                                                                    limits_.max_abs_position_mm));
            row_records_.push_back(r);
        }
        for (int c : {kA, kB, kC}) (void)number(c, line_no);  // validated; rotary axes are not modelled yet
        if (const auto f = number(kFeed, line_no)) {
            Record fr{time_of(time_of_feed_, line_no), line_no, Chan::Feed, {*f, 0, 0}, -1};
            if (*f < 0 || *f > limits_.max_feed_mm_min)
                diag_.warn("out_of_range", line_no, fmt::format("feed {:.1f} mm/min outside 0..{}", *f, limits_.max_feed_mm_min));
            row_records_.push_back(fr);
        }
        if (const auto s = number(kSpindle, line_no)) {
            Record sr{time_of(time_of_spindle_, line_no), line_no, Chan::Spindle, {*s, 0, 0}, -1};
            if (std::fabs(*s) > limits_.max_abs_spindle_rpm)
                diag_.warn("out_of_range", line_no, fmt::format("spindle {:.0f} rpm beyond +-{}", *s, limits_.max_abs_spindle_rpm));
            row_records_.push_back(sr);
        }
        if (cols_[kBlock].index >= 0) {
            const std::string_view b = fields_[static_cast<std::size_t>(cols_[kBlock].index)];
            if (!b.empty()) {
                Record br{time_of(time_of_block_, line_no), line_no, Chan::Block, {0, 0, 0}, blocks_.intern(b)};
                row_records_.push_back(br);
            }
        }
        if (const auto tool = number(kTool, line_no)) {
            if (*tool < 0 || *tool > 99999999 || *tool != std::floor(*tool))
                diag_.fail(line_no, fmt::format("column '{}': '{}' is not a tool number (a whole number from 0)", cols_[kTool].header,
                                                fields_[static_cast<std::size_t>(cols_[kTool].index)]));
            Record tr{time_of(time_of_block_, line_no), line_no, Chan::Tool, {*tool, 0, 0}, -1};
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
    StageLimits limits_;
    std::array<Column, kNumCols> cols_{};
    std::vector<std::string_view> fields_;
    std::vector<Record> row_records_;
    std::size_t n_fields_ = 0;
    int time_of_pos_ = kT, time_of_feed_ = kT, time_of_spindle_ = kT, time_of_block_ = kT;
};

}  // namespace

void read_csv(const std::string& path, const ReadOptions& opt, Diagnostics& diag, BlockTable& blocks, RecordSink& out) {
    CsvReader(path, opt, diag, blocks, out).run();
}

}  // namespace cutload::motion_io::detail
