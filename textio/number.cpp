#include "textio/number.hpp"

#include <charconv>
#include <cmath>
#include <cstring>

namespace cutload::textio {
namespace {

constexpr std::string_view kNbsp = "\xC2\xA0", kNarrowNbsp = "\xE2\x80\xAF";

// Length of the blank at the front of s (0 when none).
std::size_t blank_at(std::string_view s) {
    if (s.empty()) return 0;
    if (s[0] == ' ' || s[0] == '\t') return 1;
    if (s.substr(0, 2) == kNbsp) return 2;
    if (s.substr(0, 3) == kNarrowNbsp) return 3;
    return 0;
}

std::size_t blank_before(std::string_view s) {
    if (s.empty()) return 0;
    if (s.back() == ' ' || s.back() == '\t') return 1;
    if (s.size() >= 2 && s.substr(s.size() - 2) == kNbsp) return 2;
    if (s.size() >= 3 && s.substr(s.size() - 3) == kNarrowNbsp) return 3;
    return 0;
}

// Digits grouped by blanks or an apostrophe: what remains once they are taken out reads as a number.
bool grouped(std::string_view s, bool decimal_comma) {
    std::string plain;
    bool had_group = false;
    while (!s.empty()) {
        if (const std::size_t b = blank_at(s)) {
            s.remove_prefix(b);
            had_group = true;
        } else if (s.front() == '\'' || s.substr(0, 3) == "\xE2\x80\x99") {
            s.remove_prefix(s.front() == '\'' ? 1 : 3);
            had_group = true;
        } else {
            plain += s.front();
            s.remove_prefix(1);
        }
    }
    return had_group && static_cast<bool>(parse_number(plain, decimal_comma));
}

}  // namespace

std::string_view trim_blanks(std::string_view s) {
    while (const std::size_t b = blank_at(s)) s.remove_prefix(b);
    while (const std::size_t b = blank_before(s)) s.remove_suffix(b);
    return s;
}

ParsedNumber parse_number(std::string_view text, bool decimal_comma) {
    std::string_view s = trim_blanks(text);
    if (s.empty()) return {0, NumberError::empty};
    if (s.front() == '+') s.remove_prefix(1);
    char buf[64];
    if (decimal_comma) {
        if (const std::size_t comma = s.find(','); comma != std::string_view::npos) {
            // One comma and no point; "1.234,5" (a thousands point) would otherwise read as 1.234.
            if (s.find('.') != std::string_view::npos || s.find(',', comma + 1) != std::string_view::npos)
                return {0, NumberError::digit_group};
            if (s.size() >= sizeof buf) return {0, NumberError::not_a_number};
            std::memcpy(buf, s.data(), s.size());
            buf[comma] = '.';
            s = std::string_view(buf, s.size());
        }
    }
    double v = 0;
    const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
    if (r.ec == std::errc::result_out_of_range) return {0, NumberError::not_finite};
    if (r.ec != std::errc() || r.ptr != s.data() + s.size())
        return {0, grouped(s, decimal_comma) ? NumberError::digit_group : NumberError::not_a_number};
    if (!std::isfinite(v)) return {0, NumberError::not_finite};
    return {v, NumberError::none};
}

std::string number_problem(std::string_view text, NumberError error) {
    std::string shown;
    shown.reserve(text.size() + 2);
    shown.append(1, '\'').append(text).append(1, '\'');
    switch (error) {
        case NumberError::none: return shown + " is a number";
        case NumberError::empty: return "empty where a number is expected";
        case NumberError::not_finite: return shown + " is not a finite number";
        case NumberError::digit_group: {
            const std::string_view t = trim_blanks(text);
            const bool nbsp = t.find(kNbsp) != std::string_view::npos || t.find(kNarrowNbsp) != std::string_view::npos;
            return shown + " is not a number: " +
                   (nbsp ? "a no-break space inside it" : "a digit group separator inside it") +
                   " (digit grouping is not read: write the number without it, e.g. 1234.5)";
        }
        case NumberError::not_a_number: break;
    }
    return shown + " is not a number";
}

}  // namespace cutload::textio
