// SHDR time stamps and line classification, shared by the file reader and the live sources.
#include "motion_io/shdr.hpp"

#include <fmt/format.h>

#include <charconv>
#include <cmath>

namespace cutload::motion_io {
namespace {

constexpr std::string_view kMultiline = "--multiline--";
constexpr std::int64_t kNsPerSec = 1'000'000'000;

// Days since 1970-01-01 of a civil date (proleptic Gregorian).
std::int64_t days_from_civil(std::int64_t y, unsigned m, unsigned d) {
    y -= m <= 2;
    const std::int64_t era = (y >= 0 ? y : y - 399) / 400;
    const auto yoe = static_cast<unsigned>(y - era * 400);
    const unsigned doy = (153 * (m + (m > 2 ? -3 : 9)) + 2) / 5 + d - 1;
    const unsigned doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    return era * 146097 + static_cast<std::int64_t>(doe) - 719468;
}

// The inverse of days_from_civil.
void civil_from_days(std::int64_t z, std::int64_t& y, unsigned& m, unsigned& d) {
    z += 719468;
    const std::int64_t era = (z >= 0 ? z : z - 146096) / 146097;
    const auto doe = static_cast<unsigned>(z - era * 146097);
    const unsigned yoe = (doe - doe / 1460 + doe / 36524 - doe / 146096) / 365;
    const unsigned doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    const unsigned mp = (5 * doy + 2) / 153;
    d = doy - (153 * mp + 2) / 5 + 1;
    m = mp < 10 ? mp + 3 : mp - 9;
    y = static_cast<std::int64_t>(yoe) + era * 400 + (m <= 2);
}

bool parse_int(std::string_view s, int& v) {
    const auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
    return ec == std::errc() && p == s.data() + s.size();
}

bool is_condition(const std::vector<std::string_view>& f) {
    if (f.size() != 7) return false;
    if (f[2] == "NORMAL" || f[2] == "WARNING" || f[2] == "FAULT") return true;
    return f[2] == "UNAVAILABLE" && f[3].empty() && f[4].empty() && f[5].empty() && f[6].empty();
}

}  // namespace

std::int64_t IsoTime::nanos() const {
    // Ties and rounding past the second (a 10th digit) carry into it.
    return sec * kNsPerSec + std::llround(frac * 1e9);
}

std::optional<IsoTime> parse_iso_time(std::string_view s) {
    if (const auto at = s.find('@'); at != std::string_view::npos) s = s.substr(0, at);
    if (!s.empty() && s.back() == 'Z') s.remove_suffix(1);
    if (s.size() < 19 || s[4] != '-' || s[7] != '-' || (s[10] != 'T' && s[10] != ' ') || s[13] != ':' || s[16] != ':')
        return std::nullopt;
    int y, mo, d, h, mi, se;
    if (!parse_int(s.substr(0, 4), y) || !parse_int(s.substr(5, 2), mo) || !parse_int(s.substr(8, 2), d) ||
        !parse_int(s.substr(11, 2), h) || !parse_int(s.substr(14, 2), mi) || !parse_int(s.substr(17, 2), se))
        return std::nullopt;
    IsoTime st;
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

std::string format_iso_time(std::int64_t ns) {
    // Floor division, so instants before 1970 get a positive fraction of their second.
    std::int64_t sec = ns / kNsPerSec;
    std::int64_t sub = ns % kNsPerSec;
    if (sub < 0) sub += kNsPerSec, --sec;
    std::int64_t days = sec / 86400;
    std::int64_t sod = sec % 86400;
    if (sod < 0) sod += 86400, --days;
    std::int64_t y = 0;
    unsigned m = 0, d = 0;
    civil_from_days(days, y, m, d);
    int digits = 9;
    while (digits > 3 && sub % 10 == 0) sub /= 10, --digits;
    return fmt::format("{:04}-{:02}-{:02}T{:02}:{:02}:{:02}.{:0{}}Z", y, m, d, sod / 3600, sod / 60 % 60, sod % 60, sub,
                       digits);
}

void split_shdr_fields(std::string_view line, std::vector<std::string_view>& out) {
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

ShdrLineKind ShdrLineTokenizer::next(std::string_view line) {
    fields_.clear();
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    if (!terminator_.empty()) {
        if (line == terminator_) terminator_.clear();
        return ShdrLineKind::Body;
    }
    if (line.empty()) return ShdrLineKind::Blank;
    if (line.front() == '*') return ShdrLineKind::Command;
    split_shdr_fields(line, fields_);
    if (fields_.size() < 3) return ShdrLineKind::Short;
    const bool asset = fields_[1].substr(0, 1) == "@";
    if (fields_.back().substr(0, kMultiline.size()) == kMultiline) {
        terminator_ = std::string(fields_.back());
        return asset ? ShdrLineKind::Asset : ShdrLineKind::Multiline;
    }
    if (asset) return ShdrLineKind::Asset;
    if (is_condition(fields_)) return ShdrLineKind::Condition;
    return ShdrLineKind::Data;
}

}  // namespace cutload::motion_io
