// Internal to server: number text for the large series answers (forces, motion windows), where
// formatting is most of a request's cost (20000 numbers for a 4-channel window of 2000 buckets).
// These print through integers, about 1.4x faster than shortest round-trip std::to_chars and
// with shorter text:
// - values: 7 significant digits (a float carries 7.2), trailing zeros trimmed;
// - times: rounded to the microsecond (samples are >= 30 us apart), trailing zeros trimmed.
#pragma once

#include <bit>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>

namespace cutload::server {

// Room one number needs at most, separator included: "-1.2345678e-05" for a value,
// "-1.2345678901234567e+300" for a time.
constexpr std::size_t kValueChars = 16;
constexpr std::size_t kTimeChars = 26;

namespace detail {

constexpr std::uint64_t kPow10[] = {1ULL,
                                    10ULL,
                                    100ULL,
                                    1000ULL,
                                    10000ULL,
                                    100000ULL,
                                    1000000ULL,
                                    10000000ULL,
                                    100000000ULL,
                                    1000000000ULL,
                                    10000000000ULL,
                                    100000000000ULL,
                                    1000000000000ULL,
                                    10000000000000ULL,
                                    100000000000000ULL,
                                    1000000000000000ULL,
                                    10000000000000000ULL,
                                    100000000000000000ULL,
                                    1000000000000000000ULL,
                                    10000000000000000000ULL};

inline constexpr char kDigitPairs[] =
    "00010203040506070809101112131415161718192021222324252627282930313233343536373839"
    "40414243444546474849505152535455565758596061626364656667686970717273747576777879"
    "8081828384858687888990919293949596979899";

inline int decimal_digits(std::uint64_t x) {
    const int t = (static_cast<int>(std::bit_width(x)) * 1233) >> 12;   // log10(2) ~ 1233 / 4096
    return t - (x < kPow10[t] ? 1 : 0) + 1;
}

// scaled / 10^decimals in decimal without the fraction's trailing zeros, written right to left
// two digits at a time.
inline char* write_fixed(char* p, std::uint64_t scaled, int decimals) {
    while (decimals > 0 && scaled % 10 == 0) {
        scaled /= 10;
        --decimals;
    }
    const int digits = decimal_digits(scaled);
    const int whole = digits > decimals ? digits - decimals : 1;   // "0.xx" when all are decimals
    char* const end = p + whole + (decimals > 0 ? decimals + 1 : 0);
    char* q = end;
    auto put = [&](int n) {
        for (; n >= 2; n -= 2) {
            q -= 2;
            std::memcpy(q, &kDigitPairs[(scaled % 100) * 2], 2);
            scaled /= 100;
        }
        if (n == 1) {
            *--q = static_cast<char>('0' + scaled % 10);
            scaled /= 10;
        }
    };
    put(decimals);
    if (decimals > 0) *--q = '.';
    put(whole);
    return end;
}

inline char* write_text(char* p, const char* s) {
    const std::size_t n = std::strlen(s);
    std::memcpy(p, s, n);
    return p + n;
}

}  // namespace detail

// 7 significant digits; non-finite values are written as `nonfinite` ("null" in JSON).
inline char* write_float(char* p, float v, const char* nonfinite = "null") {
    if (!std::isfinite(v)) return detail::write_text(p, nonfinite);
    if (v == 0) {
        *p++ = '0';
        return p;
    }
    *p = '-';
    p += std::signbit(v) ? 1 : 0;   // without a branch: signs of force samples alternate at random
    const float a = std::fabs(v);
    // Outside 1e-3 .. 1e9 the shortest form (with an exponent) is both short and rare.
    if (a < 1e-3f || a >= 1e9f) return std::to_chars(p, p + kValueChars, a).ptr;
    // floor(log10(a)) from the binary exponent (log10(2) ~ 1233 / 4096), then one correction.
    std::uint32_t bits;
    std::memcpy(&bits, &a, sizeof bits);
    const int e2 = static_cast<int>((bits >> 23) & 0xff) - 127;
    int e = (e2 * 1233) >> 12;
    if (e < 8 && static_cast<double>(a) >= static_cast<double>(detail::kPow10[e + 4]) * 1e-3) ++e;
    const int decimals = e >= 6 ? 0 : 6 - e;
    const double scaled = static_cast<double>(a) * static_cast<double>(detail::kPow10[decimals]) + 0.5;
    return detail::write_fixed(p, static_cast<std::uint64_t>(scaled), decimals);
}

// Seconds rounded to the microsecond; non-finite as `nonfinite`.
inline char* write_time(char* p, double t_s, const char* nonfinite = "null") {
    if (!std::isfinite(t_s)) return detail::write_text(p, nonfinite);
    if (std::fabs(t_s) >= 1e12) return std::to_chars(p, p + kTimeChars, t_s).ptr;
    if (t_s < 0) *p++ = '-';
    return detail::write_fixed(p, static_cast<std::uint64_t>(std::fabs(t_s) * 1e6 + 0.5), 6);
}

}  // namespace cutload::server
