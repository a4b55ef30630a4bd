// Decimal numbers as exports print them: 258.428, -1.98E+02, +5, and with decimal_comma 0,125.
// Blanks around a number are dropped: spaces, tabs, and the no-break spaces a spreadsheet leaves
// (U+00A0, a 0xA0 byte in a Windows-1252/Latin-1 export once decoded; U+202F), so `12.5\xA0` is
// 12.5. A blank *inside* a number is refused, never read as a digit group: `1\xA0234.5` could be
// 1234.5 or two numbers, and a silent wrong number is worse than an error that names the place.
#pragma once

#include <charconv>
#include <string>
#include <string_view>

namespace cutload::textio {

enum class NumberError {
    none,
    empty,          // nothing but blanks
    not_a_number,
    not_finite,     // inf, nan, or out of the double range
    digit_group,    // a blank or a thousands separator inside the number
};

struct ParsedNumber {
    double value = 0;
    NumberError error = NumberError::none;
    explicit operator bool() const { return error == NumberError::none; }
};

// `text` must be UTF-8 (decoded). With decimal_comma (exports separated by ';' or tab), one ','
// and no '.' is the decimal mark: "0,125" is 0.125; "1.234,5" is refused as a digit group.
ParsedNumber parse_number(std::string_view text, bool decimal_comma = false);

// `text` without the blanks around it (ASCII space and tab, U+00A0, U+202F).
std::string_view trim_blanks(std::string_view text);

// Why `text` is not a number, for a message: "'1 234.5' is not a number: a no-break space inside
// it (digit grouping is not read; write 1234.5)". `text` is echoed as is (it must be UTF-8).
std::string number_problem(std::string_view text, NumberError error);

// std::to_chars(first, last, value, std::chars_format::fixed, decimals), the same characters
// (the double's exact value rounded half to even, "-" on any negative value, -0.0 included),
// several times faster for what result files hold: finite values under 2^52 with up to 9
// decimals; others go through std::to_chars itself. FORCES.csv prints about 3 million numbers
// for a 10 s log, which std::to_chars made the longest part of a short prediction.
std::to_chars_result format_fixed(char* first, char* last, double value, int decimals);

}  // namespace cutload::textio
