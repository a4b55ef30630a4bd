// CSV as RFC 4180 writes it, read and written in one place.
//
// Reading (CsvReader): records from a stream, one at a time, in bounded memory. A field wrapped in
// double quotes may hold the delimiter, line breaks and doubled quotes ("" is one "). Beyond the
// RFC, as exports write it: a delimiter other than ',' (`;` and tab exports), detected per record
// when asked; blanks around unquoted fields and around quotes dropped (trim); '#' comment lines
// and blank lines skipped when asked; a quote inside an unquoted field is an ordinary character
// (`12" vise`). Errors name source, line and column: a quoted field never closed, text after a
// closing quote, a field or record longer than its limit (an unclosed quote would otherwise
// swallow the rest of the file), a byte that is not text (text.hpp).
//
// Writing (append_field): a field is quoted exactly when it must be: when it holds the delimiter,
// a double quote, CR or LF, or begins or ends with a blank (which a trimming reader would drop).
#pragma once

#include "textio/lines.hpp"

#include <cstddef>
#include <istream>
#include <string>
#include <string_view>
#include <vector>

namespace cutload::textio {

struct CsvOptions {
    char delimiter = ',';          // 0: detect per record from its first line (detect_delimiter)
    char comment = 0;              // e.g. '#': a line starting with it (after blanks) is skipped
    bool skip_blank_lines = true;
    bool trim = true;              // drop spaces and tabs around unquoted fields and around quotes
    std::size_t max_field_bytes = std::size_t{64} << 10;   // 64 KiB
    std::size_t max_record_bytes = kDefaultMaxLineBytes;   // also the limit of one line
};

// The delimiter a line uses, counted outside quotes: tab if it holds one, else ';' if it holds
// one, else ','. (A `;` export writes decimal commas, so commas do not decide.)
char detect_delimiter(std::string_view line);

class CsvReader {
public:
    CsvReader(std::istream& in, std::string source, CsvOptions opt = {});

    // Reads the next record; false at the end of the input. Throws TextError.
    bool next();

    std::size_t size() const { return spans_.size(); }
    std::string_view operator[](std::size_t i) const { return {base_ + spans_[i].offset, spans_[i].length}; }
    bool quoted(std::size_t i) const { return spans_[i].quoted; }
    std::size_t line() const { return record_line_; }               // where the record starts
    std::size_t line_of(std::size_t i) const { return spans_[i].line; }
    std::size_t column_of(std::size_t i) const { return spans_[i].column; }   // 1-based characters
    char delimiter() const { return delimiter_; }                   // of the last record
    void set_delimiter(char d) { opt_.delimiter = d; }              // for the records that follow
    const std::string& source() const { return lines_.source(); }

    // Throw TextError at field i (its line and column) or at the record's line.
    [[noreturn]] void fail(std::size_t field, const std::string& what) const;
    [[noreturn]] void fail(const std::string& what) const;

private:
    struct Span {
        std::size_t offset = 0, length = 0, line = 0, column = 0;
        bool quoted = false;
    };
    void split_simple(std::string_view line, bool ascii);
    void split_quoted(std::string_view line);
    bool is_blank(char c) const { return c == ' ' || (c == '\t' && delimiter_ != '\t'); }

    LineReader lines_;
    CsvOptions opt_;
    char delimiter_ = ',';
    const char* base_ = nullptr;   // fields point into the line (no quotes) or into store_
    std::string store_;
    std::vector<Span> spans_;
    std::size_t record_line_ = 0;
};

// True when `field` must be quoted (see above).
bool needs_quotes(std::string_view field, char delimiter = ',');
// Appends `field` to `out`, quoted with inner quotes doubled exactly when needs_quotes().
void append_field(std::string& out, std::string_view field, char delimiter = ',');
// The field as append_field() writes it.
std::string csv_field(std::string_view field, char delimiter = ',');

}  // namespace cutload::textio
