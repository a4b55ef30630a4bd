#include "textio/csv.hpp"

#include <cstring>

namespace cutload::textio {
namespace {

// Character columns along one line, counted as the scan moves right (never quadratic).
class Columns {
public:
    void reset(std::string_view line, bool ascii) {
        line_ = line;
        ascii_ = ascii;
        upto_ = 0;
        chars_ = 0;
    }
    std::size_t at(std::size_t byte) {
        if (ascii_) return byte + 1;
        if (byte < upto_) {
            upto_ = 0;
            chars_ = 0;
        }
        for (; upto_ < byte && upto_ < line_.size(); ++upto_) chars_ += (static_cast<unsigned char>(line_[upto_]) & 0xC0) != 0x80;
        return chars_ + 1;
    }

private:
    std::string_view line_;
    bool ascii_ = true;
    std::size_t upto_ = 0, chars_ = 0;
};

std::string too_long(const char* what, std::size_t limit) {
    return std::string(what) + " longer than " + std::to_string(limit) + " bytes (a quote never closed?)";
}

}  // namespace

char detect_delimiter(std::string_view line) {
    bool quoted = false, semicolon = false;
    for (const char c : line) {
        if (c == '"') quoted = !quoted;
        if (quoted) continue;
        if (c == '\t') return '\t';
        semicolon = semicolon || c == ';';
    }
    return semicolon ? ';' : ',';
}

CsvReader::CsvReader(std::istream& in, std::string source, CsvOptions opt)
    : lines_(in, std::move(source), opt.max_record_bytes), opt_(opt) {}

bool CsvReader::next() {
    spans_.clear();
    while (lines_.next()) {
        const std::string_view text = lines_.text();
        if (opt_.skip_blank_lines || opt_.comment) {
            const std::size_t first = text.find_first_not_of(" \t");
            if (first == std::string_view::npos) {
                if (opt_.skip_blank_lines) continue;
            } else if (opt_.comment && text[first] == opt_.comment) {
                continue;
            }
        }
        record_line_ = lines_.number();
        delimiter_ = opt_.delimiter ? opt_.delimiter : detect_delimiter(text);
        if (std::memchr(text.data(), '"', text.size()) == nullptr)
            split_simple(text, lines_.ascii());
        else
            split_quoted(text);
        return true;
    }
    return false;
}

// No quote on the line: the fields are views into it.
void CsvReader::split_simple(std::string_view line, bool ascii) {
    base_ = line.data();
    Columns cols;
    cols.reset(line, ascii);
    std::size_t start = 0;
    while (true) {
        const void* hit = std::memchr(line.data() + start, delimiter_, line.size() - start);
        const std::size_t stop = hit ? static_cast<std::size_t>(static_cast<const char*>(hit) - line.data()) : line.size();
        std::size_t a = start, b = stop;
        if (opt_.trim) {
            while (a < b && is_blank(line[a])) ++a;
            while (b > a && is_blank(line[b - 1])) --b;
        }
        spans_.push_back({a, b - a, record_line_, cols.at(a), false});
        if (b - a > opt_.max_field_bytes) fail(spans_.size() - 1, too_long("field", opt_.max_field_bytes));
        if (!hit) return;
        start = stop + 1;
    }
}

// Quotes on the line: a state machine that may continue over following lines; fields are copied
// (unquoted) into store_.
void CsvReader::split_quoted(std::string_view line) {
    store_.clear();
    Columns cols;
    cols.reset(line, lines_.ascii());
    std::size_t line_no = lines_.number();
    std::size_t i = 0;
    auto check_record = [&] {
        if (store_.size() > opt_.max_record_bytes)
            throw TextError(source(), record_line_, 0, too_long("record", opt_.max_record_bytes));
    };
    while (true) {
        if (opt_.trim)
            while (i < line.size() && is_blank(line[i])) ++i;
        if (i < line.size() && line[i] == '"') {
            Span s{store_.size(), 0, line_no, cols.at(i), true};
            ++i;
            while (true) {
                const std::size_t q = line.find('"', i);
                if (q == std::string_view::npos) {
                    // The field goes on over the line break.
                    store_.append(line.substr(i));
                    store_ += '\n';
                    if (store_.size() - s.offset > opt_.max_field_bytes)
                        throw TextError(source(), s.line, s.column, too_long("quoted field", opt_.max_field_bytes));
                    check_record();
                    if (!lines_.next())
                        throw TextError(source(), s.line, s.column, "quoted field never closed: the file ends inside it");
                    line = lines_.text();
                    line_no = lines_.number();
                    cols.reset(line, lines_.ascii());
                    i = 0;
                    continue;
                }
                store_.append(line.substr(i, q - i));
                if (q + 1 < line.size() && line[q + 1] == '"') {
                    store_ += '"';
                    i = q + 2;
                    continue;
                }
                i = q + 1;
                break;
            }
            s.length = store_.size() - s.offset;
            if (s.length > opt_.max_field_bytes)
                throw TextError(source(), s.line, s.column, too_long("quoted field", opt_.max_field_bytes));
            spans_.push_back(s);
            if (opt_.trim)
                while (i < line.size() && is_blank(line[i])) ++i;
            if (i == line.size()) break;
            if (line[i] != delimiter_)
                throw TextError(source(), line_no, cols.at(i),
                                "text after the closing quote of a field (a quote inside a quoted field is written \"\")");
            ++i;
        } else {
            const std::size_t end = line.find(delimiter_, i);
            const std::size_t stop = end == std::string_view::npos ? line.size() : end;
            std::size_t b = stop;
            if (opt_.trim)
                while (b > i && is_blank(line[b - 1])) --b;
            Span s{store_.size(), b - i, line_no, cols.at(i), false};
            if (s.length > opt_.max_field_bytes) throw TextError(source(), s.line, s.column, too_long("field", opt_.max_field_bytes));
            store_.append(line.substr(i, b - i));
            spans_.push_back(s);
            if (end == std::string_view::npos) break;
            i = end + 1;
        }
        check_record();
    }
    check_record();
    base_ = store_.data();
}

void CsvReader::fail(std::size_t field, const std::string& what) const {
    if (field >= spans_.size()) fail(what);
    throw TextError(source(), spans_[field].line, spans_[field].column, what);
}

void CsvReader::fail(const std::string& what) const { throw TextError(source(), record_line_, 0, what); }

bool needs_quotes(std::string_view field, char delimiter) {
    if (field.empty()) return false;
    const auto blank = [](char c) { return c == ' ' || c == '\t'; };
    if (blank(field.front()) || blank(field.back())) return true;
    for (const char c : field)
        if (c == delimiter || c == '"' || c == '\n' || c == '\r') return true;
    return false;
}

void append_field(std::string& out, std::string_view field, char delimiter) {
    if (!needs_quotes(field, delimiter)) {
        out.append(field);
        return;
    }
    out += '"';
    for (const char c : field) {
        if (c == '"') out += '"';
        out += c;
    }
    out += '"';
}

std::string csv_field(std::string_view field, char delimiter) {
    std::string out;
    append_field(out, field, delimiter);
    return out;
}

}  // namespace cutload::textio
