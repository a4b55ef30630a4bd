// Streaming reader for dynamometer exports. Records come from textio's CSV reader (RFC 4180 quoting,
// text decoded: a Latin-1 `Temperatur [°C]` column reads as what it says), fields as string_views
// and numbers through std::from_chars, so 10^7 rows read in seconds and only three floats per row
// are kept.
#include "force_model/measurement.hpp"

#include "textio/csv.hpp"
#include "textio/number.hpp"
#include "textio/text.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <fstream>
#include <optional>
#include <sstream>
#include <string_view>

namespace cutload::force_model {

namespace {

std::string_view trim(std::string_view s) { return textio::trim_blanks(s); }

std::string lower(std::string_view s) {
    std::string out(s);
    for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return out;
}

// A decimal comma (European exports, which separate fields by ';' or tab): "0,125" is 0.125. A
// field holds a comma only when the separator is not one; "1.234,5" (a thousands point) is refused.
std::optional<double> number(std::string_view s, bool decimal_comma = true) {
    const textio::ParsedNumber p = textio::parse_number(s, decimal_comma);
    if (!p) return std::nullopt;
    return p.value;
}

// A column name without its unit: "Fx [N]" -> ("fx", "N"), "t_ms" -> ("t", "ms"), "Time" -> ("time", "").
struct ColumnName {
    std::string name, unit;
};

ColumnName parse_column_name(std::string_view field) {
    ColumnName c;
    std::string_view s = trim(field);
    const std::size_t open = s.find_first_of("[(");
    if (open != std::string_view::npos) {
        const std::size_t close = s.find_first_of("])", open);
        c.unit = std::string(trim(s.substr(open + 1, close == std::string_view::npos ? close : close - open - 1)));
        s = trim(s.substr(0, open));
    }
    c.name = lower(s);
    const std::size_t us = c.name.rfind('_');
    if (c.unit.empty() && us != std::string::npos) {
        const std::string suffix = c.name.substr(us + 1);
        if (suffix == "s" || suffix == "ms" || suffix == "n" || suffix == "kn") {
            c.unit = suffix == "n" ? "N" : suffix == "kn" ? "kN" : suffix;
            c.name.resize(us);
        }
    }
    return c;
}

bool is_time_name(const std::string& n) { return n == "time" || n == "t"; }

std::optional<double> time_scale(std::string_view unit) {
    const std::string u = lower(trim(unit));
    if (u == "s" || u == "sec") return 1.0;
    if (u == "ms") return 1e-3;
    if (u == "us" || u == "\xc2\xb5s" || u == "\xce\xbcs") return 1e-6;
    return std::nullopt;
}

// Readings no instrument gives: they come from a wrong unit or a damaged file, and a force past
// float's range would turn into infinity in the stored channel. The largest dynamometers measure
// some hundreds of kN.
constexpr double kMaxForce_N = 1e6;
constexpr double kMaxTime_s = 1e9;
constexpr double kMaxRate_Hz = 1e7;

std::optional<double> force_scale(std::string_view unit) {
    const std::string u = lower(trim(unit));
    if (u == "n") return 1.0;
    if (u == "kn") return 1e3;
    if (u == "dan") return 10.0;
    return std::nullopt;
}

class Reader {
public:
    Reader(std::istream& in, std::string source, const MeasurementWindow& w)
        : csv_(in, textio::printable(source), csv_options()), window_(w) {
        m_.source = textio::printable(source);
    }

    Measurement read() {
        try {
            read_header();
            read_data();
        } catch (const textio::TextError& e) {
            throw MeasurementError(e.what());
        }
        return std::move(m_);
    }

private:
    static textio::CsvOptions csv_options() {
        textio::CsvOptions o;
        o.delimiter = 0;   // per line in the metadata; the names row's from there on
        return o;
    }

    [[noreturn]] void fail(const std::string& what) const {
        throw MeasurementError(fmt::format("{}:{}: {}", m_.source, line_no_, what));
    }
    // At the field's line and character column when the current record has it.
    [[noreturn]] void fail_column(std::size_t col, const std::string& what) const {
        const std::string where = col < csv_.size() && csv_.line() == line_no_
                                      ? fmt::format("{}:{}:{}", m_.source, csv_.line_of(col), csv_.column_of(col))
                                      : fmt::format("{}:{}", m_.source, line_no_);
        throw MeasurementError(fmt::format("{}: column {} ({}): {}", where, col + 1, column_label(col), what));
    }
    std::string not_a_number(std::size_t col) const {
        const textio::ParsedNumber p = textio::parse_number(csv_[col], decimal_comma_);
        return textio::number_problem(csv_[col], p.error == textio::NumberError::none ? textio::NumberError::not_a_number : p.error);
    }
    std::string column_label(std::size_t col) const {
        return col < names_.size() ? names_[col] : std::string("beyond the names row");
    }

    // The next non-blank record as fields (views valid until the next call).
    bool next_record(std::vector<std::string_view>& fields) {
        fields.clear();
        if (!csv_.next()) return false;
        line_no_ = csv_.line();
        for (std::size_t i = 0; i < csv_.size(); ++i) fields.push_back(csv_[i]);
        return true;
    }
    // The record as written, for messages.
    std::string record_text(const std::vector<std::string_view>& fields) const {
        std::string s;
        for (std::size_t i = 0; i < fields.size(); ++i) {
            if (i) s += csv_.delimiter();
            textio::append_field(s, fields[i], csv_.delimiter());
        }
        return s;
    }

    // Metadata up to the names row; the units row when there is one.
    void read_header() {
        bool dynoware = false;
        std::size_t metadata_lines = 0;
        std::vector<std::string_view> fields;
        while (true) {
            if (!next_record(fields))
                fail("no column names row found (expected a row such as `Time,Fx,Fy,Fz` or `t,fx,fy,fz`)");
            const ColumnName first = parse_column_name(fields[0]);
            if (line_no_ == 1 && lower(fields[0]).rfind("dynoware", 0) == 0) dynoware = true;
            if (is_time_name(first.name) || has_force_columns(fields)) {
                set_columns(fields);
                break;
            }
            if (number(fields[0]))
                fail(fmt::format("data row before the column names row (found `{}`; expected a row such as "
                                 "`Time,Fx,Fy,Fz`)",
                                 textio::first_characters(record_text(fields), 60)));
            read_metadata(fields);
            ++metadata_lines;
        }
        m_.format = dynoware || metadata_lines > 0 ? "dynoware" : "csv";
        const std::size_t names_line = line_no_;
        // Units row: the next non-empty line when its time or force fields are not numbers.
        if (!next_record(fields)) fail("no data rows after the column names");
        const std::vector<std::size_t> used = used_columns();
        const bool units_row = std::any_of(used.begin(), used.end(), [&](std::size_t c) {
            return c < fields.size() && !number(fields[c]);
        });
        if (units_row) {
            read_units(fields);
            pending_row_ = false;
        } else {
            if (m_.format == "dynoware")
                fail(fmt::format("missing units row after the column names on line {} (a DynoWare export "
                                 "has one, e.g. `s,N,N,N`)",
                                 names_line));
            pending_row_ = true;
        }
        finish_units(names_line);
    }

    bool has_force_columns(const std::vector<std::string_view>& fields) const {
        int found = 0;
        for (auto f : fields) {
            const std::string n = parse_column_name(f).name;
            found += n == "fx" || n == "fy" || n == "fz";
        }
        return found >= 2;
    }

    void read_metadata(const std::vector<std::string_view>& fields) {
        const std::string key = lower(fields[0]);
        if (key.rfind("sampling rate", 0) != 0 && key.rfind("sample rate", 0) != 0) return;
        const std::optional<double> v = fields.size() > 1 ? number(fields[1], csv_.delimiter() != ',') : std::nullopt;
        if (!v || *v <= 0) fail(fmt::format("sampling rate `{}` is not a positive number", record_text(fields)));
        const double scale = key.find("khz") != std::string::npos ? 1e3 : 1.0;
        header_rate_Hz_ = *v * scale;
        if (*header_rate_Hz_ > 1e7) fail(fmt::format("sampling rate {} Hz is implausible", *header_rate_Hz_));
    }

    void set_columns(const std::vector<std::string_view>& fields) {
        // The names row fixes the separator of everything below it.
        csv_.set_delimiter(csv_.delimiter());
        decimal_comma_ = csv_.delimiter() != ',';
        for (std::size_t i = 0; i < fields.size(); ++i) {
            const ColumnName c = parse_column_name(fields[i]);
            names_.push_back(std::string(fields[i]));
            units_.push_back(c.unit);
            std::optional<std::size_t>* slot = nullptr;
            if (i == 0 && is_time_name(c.name)) slot = &col_time_;
            if (c.name == "fx") slot = &col_f_[0];
            if (c.name == "fy") slot = &col_f_[1];
            if (c.name == "fz") slot = &col_f_[2];
            if (!slot) {
                if (!c.name.empty()) m_.ignored_channels.push_back(std::string(fields[i]));
                continue;
            }
            if (*slot) fail_column(i, "appears twice in the names row");
            *slot = i;
        }
        static const char* force_names[3] = {"Fx", "Fy", "Fz"};
        std::string found;
        for (const auto& n : names_) found += (found.empty() ? "" : ", ") + n;
        for (int a = 0; a < 3; ++a)
            if (!col_f_[a]) fail(fmt::format("no {} column in the names row (found: {})", force_names[a], found));
        max_col_ = std::max({*col_f_[0], *col_f_[1], *col_f_[2], col_time_.value_or(0)});
    }

    std::vector<std::size_t> used_columns() const {
        std::vector<std::size_t> c{*col_f_[0], *col_f_[1], *col_f_[2]};
        if (col_time_) c.push_back(*col_time_);
        return c;
    }

    void read_units(const std::vector<std::string_view>& fields) {
        for (std::size_t c : used_columns()) {
            if (c >= fields.size() || fields[c].empty())
                fail_column(c, "missing unit in the units row (expected s for time, N for forces)");
            if (!units_[c].empty() && lower(units_[c]) != lower(fields[c]))
                fail_column(c, fmt::format("unit `{}` in the units row contradicts `{}` in the names row", fields[c],
                                           units_[c]));
            units_[c] = std::string(fields[c]);
        }
    }

    // Unit scales; a plain CSV without units is taken as seconds and newtons (documented).
    void finish_units(std::size_t names_line) {
        const std::size_t saved = line_no_;
        line_no_ = names_line;
        if (col_time_) {
            const std::string& u = units_[*col_time_];
            const auto s = u.empty() ? std::optional<double>(1.0) : time_scale(u);
            if (!s) fail_column(*col_time_, fmt::format("unknown time unit `{}` (expected s, ms or us)", u));
            time_scale_ = *s;
        } else if (!header_rate_Hz_) {
            fail("no time column and no `Sampling rate [Hz]:` line: the sample times are unknown");
        }
        for (int a = 0; a < 3; ++a) {
            const std::string& u = units_[*col_f_[a]];
            const auto s = u.empty() ? std::optional<double>(1.0) : force_scale(u);
            if (!s) fail_column(*col_f_[a], fmt::format("unknown force unit `{}` (expected N, daN or kN)", u));
            force_scale_[a] = *s;
        }
        line_no_ = saved;
    }

    void read_data() {
        bool have = pending_row_;
        if (!have) have = csv_.next();
        std::size_t rows = 0;
        double t_first = 0, t_prev = 0;
        std::optional<std::size_t> first_kept;
        for (; have; have = csv_.next()) {
            line_no_ = csv_.line();
            if (csv_.size() <= max_col_)
                fail(fmt::format("{} columns where the names row has {}", csv_.size(), names_.size()));
            double t = 0;
            if (col_time_) {
                const auto v = number(csv_[*col_time_], decimal_comma_);
                if (!v) fail_column(*col_time_, not_a_number(*col_time_));
                t = *v * time_scale_;
                if (!(std::abs(t) <= kMaxTime_s))
                    fail_column(*col_time_, fmt::format("time {:g} s is beyond \u00b1{:g} s (a wrong time unit?)", t, kMaxTime_s));
            } else {
                t = static_cast<double>(rows) / *header_rate_Hz_;
            }
            float f[3];
            for (int a = 0; a < 3; ++a) {
                const auto v = number(csv_[*col_f_[a]], decimal_comma_);
                if (!v) fail_column(*col_f_[a], not_a_number(*col_f_[a]));
                const double force_N = *v * force_scale_[a];
                if (!(std::abs(force_N) <= kMaxForce_N))
                    fail_column(*col_f_[a], fmt::format("force {:g} N is beyond \u00b1{:g} N (not a dynamometer reading)",
                                                        force_N, kMaxForce_N));
                f[a] = static_cast<float>(force_N);
            }
            if (rows == 0) {
                t_first = t;
            } else {
                check_step(t - t_prev, t_prev, rows == 1 ? 0.0 : (t_prev - t_first) / static_cast<double>(rows - 1));
            }
            if (t >= window_.t_start_s && t <= window_.t_end_s) {
                if (!first_kept) first_kept = rows;
                m_.fx_N.push_back(f[0]);
                m_.fy_N.push_back(f[1]);
                m_.fz_N.push_back(f[2]);
            }
            t_prev = t;
            ++rows;
        }
        if (rows == 0) fail("no data rows after the column names");
        if (rows < 2) fail("a single data row: the sampling rate is unknown");
        const double rate = static_cast<double>(rows - 1) / (t_prev - t_first);
        if (!(rate <= kMaxRate_Hz))
            throw MeasurementError(fmt::format("{}: the time column gives {:.6g} samples a second, beyond {:g} "
                                               "(a wrong time unit?)",
                                               m_.source, rate, kMaxRate_Hz));
        if (header_rate_Hz_ && std::abs(rate / *header_rate_Hz_ - 1) > 1e-3)
            throw MeasurementError(fmt::format("{}: the time column gives {:.6g} Hz but the header says {:.6g} Hz",
                                               m_.source, rate, *header_rate_Hz_));
        m_.rate_Hz = header_rate_Hz_.value_or(rate);
        m_.file_t_start_s = t_first;
        m_.file_t_end_s = t_prev;
        if (!first_kept)
            throw MeasurementError(fmt::format("{}: no samples in the window [{:g}, {:g}] s; the file covers [{:g}, {:g}] s",
                                               m_.source, window_.t_start_s, window_.t_end_s, t_first, t_prev));
        m_.t0_s = t_first + static_cast<double>(*first_kept) / m_.rate_Hz;
    }

    // Each step must be within half an interval of the interval so far (header rate when given):
    // gaps, repeats and reversals all fail here, at their line.
    void check_step(double step_s, double t_prev, double mean_step_s) {
        const double expected = header_rate_Hz_ ? 1.0 / *header_rate_Hz_ : mean_step_s;
        if (expected == 0) {
            if (step_s > 0) return;
            fail(fmt::format("time {:g} s does not increase after {:g} s (unequal sampling)", t_prev + step_s, t_prev));
        }
        if (std::abs(step_s - expected) > 0.5 * expected)
            fail(fmt::format("time step {:.6g} s after {:.6g} s where the sampling interval is {:.6g} s "
                             "(unequal sampling: samples missing, repeated or out of order; resample the export "
                             "at a constant rate)",
                             step_s, t_prev, expected));
    }

    textio::CsvReader csv_;
    MeasurementWindow window_;
    Measurement m_;
    std::size_t line_no_ = 0;
    bool decimal_comma_ = false;
    std::vector<std::string> names_, units_;
    std::optional<std::size_t> col_time_;
    std::optional<std::size_t> col_f_[3];
    std::size_t max_col_ = 0;
    std::optional<double> header_rate_Hz_;
    double time_scale_ = 1, force_scale_[3] = {1, 1, 1};
    bool pending_row_ = false;
};

}  // namespace

Measurement read_measurement(std::istream& in, const std::string& source, const MeasurementWindow& window) {
    if (!(window.t_end_s >= window.t_start_s))
        throw MeasurementError(fmt::format("{}: empty window [{:g}, {:g}] s: the end is before the start", source,
                                           window.t_start_s, window.t_end_s));
    return Reader(in, source, window).read();
}

Measurement read_measurement(const std::string& path, const MeasurementWindow& window) {
    std::ifstream in(path);
    if (!in) throw MeasurementError(path + ": cannot open the measurement file");
    std::vector<char> buffer(1 << 20);
    in.rdbuf()->pubsetbuf(buffer.data(), static_cast<std::streamsize>(buffer.size()));
    return read_measurement(in, path, window);
}

namespace {

// A comma-separated list given on a command line or in a form field ("0,-1,0,-1,0,0,0,0,1"), as
// one CSV record (textio): one line, fields trimmed.
std::vector<std::string> comma_list(const std::string& text, const char* what) {
    std::vector<std::string> fields;
    std::istringstream in(text);
    textio::CsvReader csv(in, what);
    try {
        if (csv.next())
            for (std::size_t i = 0; i < csv.size(); ++i) fields.emplace_back(csv[i]);
        if (csv.next()) throw MeasurementError(fmt::format("{} `{}`: one line expected", what, textio::printable(text)));
    } catch (const textio::TextError& e) {
        throw MeasurementError(e.what());
    }
    return fields;
}

}  // namespace

AxisMatrix parse_axis_matrix(const std::string& text) {
    const std::vector<std::string> fields = comma_list(text, "axis matrix");
    if (fields.size() != 9)
        throw MeasurementError(fmt::format("axis matrix `{}`: {} numbers where nine (row-major 3x3) are needed", textio::printable(text),
                                           fields.size()));
    AxisMatrix a{};
    for (std::size_t i = 0; i < 9; ++i) {
        const auto v = number(fields[i], false);
        if (!v) throw MeasurementError(fmt::format("axis matrix element {} (row {}, column {}): `{}` is not a number",
                                                   i + 1, i / 3 + 1, i % 3 + 1, fields[i]));
        a[i] = *v;
    }
    const double det = a[0] * (a[4] * a[8] - a[5] * a[7]) - a[1] * (a[3] * a[8] - a[5] * a[6]) +
                       a[2] * (a[3] * a[7] - a[4] * a[6]);
    if (std::abs(det) < 1e-6) throw MeasurementError(fmt::format("axis matrix `{}` is singular", textio::printable(text)));
    return a;
}

std::array<double, 3> parse_force_vector(const std::string& text) {
    const std::vector<std::string> fields = comma_list(text, "force");
    if (fields.size() != 3)
        throw MeasurementError(fmt::format("force `{}`: {} numbers where three (Fx,Fy,Fz) are needed", textio::printable(text),
                                           fields.size()));
    std::array<double, 3> f{};
    static const char* names[3] = {"Fx", "Fy", "Fz"};
    for (std::size_t i = 0; i < 3; ++i) {
        const auto v = number(fields[i], false);
        if (!v || !std::isfinite(*v))
            throw MeasurementError(fmt::format("force `{}`: {} `{}` is not a number", textio::printable(text), names[i], fields[i]));
        f[i] = *v;
    }
    return f;
}

std::array<double, 3> to_tool_machine_axes(const std::array<double, 3>& f, const AxisMatrix& a,
                                           bool measured_on_workpiece) {
    const double s = measured_on_workpiece ? -1.0 : 1.0;
    return {s * (a[0] * f[0] + a[1] * f[1] + a[2] * f[2]), s * (a[3] * f[0] + a[4] * f[1] + a[5] * f[2]),
            s * (a[6] * f[0] + a[7] * f[1] + a[8] * f[2])};
}

void map_to_tool_machine_axes(Measurement& m, const AxisMatrix& a, bool measured_on_workpiece) {
    if (m.tool_machine_axes) throw MeasurementError(m.source + ": the measurement is already in machine axes");
    for (std::size_t i = 0; i < m.size(); ++i) {
        const auto f = to_tool_machine_axes({m.fx_N[i], m.fy_N[i], m.fz_N[i]}, a, measured_on_workpiece);
        m.fx_N[i] = static_cast<float>(f[0]);
        m.fy_N[i] = static_cast<float>(f[1]);
        m.fz_N[i] = static_cast<float>(f[2]);
    }
    m.tool_machine_axes = true;
}

}  // namespace cutload::force_model
