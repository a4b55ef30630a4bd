#include "textio/number.hpp"

#include <array>
#include <bit>
#include <cstdint>
#include <cmath>
#include <cstring>

namespace cutload::textio {
namespace {

__extension__ typedef unsigned __int128 U128;   // m * 10^9 needs 83 bits

constexpr int kFastDecimals = 9;
constexpr double kPow10Double[kFastDecimals + 1] = {1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9};
constexpr std::uint64_t kPow10[kFastDecimals + 1] = {1,         10,         100,         1000,         10000,
                                                     100000,    1000000,    10000000,    100000000,    1000000000};

// "00" to "99": two digits per division, half the dependent steps of one.
constexpr auto kDigitPairs = [] {
    std::array<char, 200> pairs{};
    for (int i = 0; i < 100; ++i) pairs[std::size_t(2 * i)] = char('0' + i / 10), pairs[std::size_t(2 * i + 1)] = char('0' + i % 10);
    return pairs;
}();

// Writes `value` in decimal to end its text just before `end`; returns where the text starts.
inline char* put_backward(char* end, std::uint64_t value) {
    char* p = end;
    while (value >= 100) {
        p -= 2;
        std::memcpy(p, kDigitPairs.data() + 2 * (value % 100), 2);
        value /= 100;
    }
    if (value >= 10) {
        p -= 2;
        std::memcpy(p, kDigitPairs.data() + 2 * value, 2);
    } else {
        *--p = char('0' + value);
    }
    return p;
}

constexpr auto kPow10To19 = [] {
    std::array<std::uint64_t, 20> pow10{};
    pow10[0] = 1;
    for (std::size_t i = 1; i < pow10.size(); ++i) pow10[i] = pow10[i - 1] * 10;
    return pow10;
}();

// Without branches (the values' magnitudes, like their signs, vary from field to field, and
// mispredicted branches were a good part of the time): the bit width gives the digit count or
// one less (1233 / 4096 is just above log10(2)), one comparison settles it.
int decimal_digits(std::uint64_t value) {
    const int low = int(std::bit_width(value | 1) * 1233 >> 12);   // 0..19
    return low + int((value | 1) >= kPow10To19[std::size_t(low)]);   // | 1: 0 has a digit too
}

// `units` (of 10^-Decimals) written at `out` as integer, point and Decimals digits; returns the
// end. Decimals is a constant, so each division is a multiplication. Written in place, front to
// back in whole fields: a staging buffer read back at once stalled on store forwarding.
template <int Decimals>
char* put_units(char* out, std::uint64_t units) {
    const std::uint64_t whole = units / kPow10[Decimals];
    out += decimal_digits(whole);
    put_backward(out, whole);
    if constexpr (Decimals > 0) {
        *out++ = '.';
        auto part = std::uint32_t(units - whole * kPow10[Decimals]);   // below 10^9
        char* p = out + Decimals;
        for (int i = 0; i + 2 <= Decimals; i += 2) {
            p -= 2;
            std::memcpy(p, kDigitPairs.data() + 2 * (part % 100), 2);
            part /= 100;
        }
        if constexpr (Decimals % 2 != 0) *--p = char('0' + part);
        out += Decimals;
    }
    return out;
}

}  // namespace

std::to_chars_result format_fixed(char* first, char* last, double value, int decimals) {
    // The longest fast result: "-", the 20 digits of a 64-bit count of units, ".": 22 characters.
    constexpr std::ptrdiff_t kFastChars = 22;
    const std::uint64_t bits = std::bit_cast<std::uint64_t>(value);
    const int biased_exp = int(bits >> 52 & 0x7ff);
    // |value| = mantissa / 2^shift exactly; shift <= 0 (|value| >= 2^52), NaN and infinities are
    // left to std::to_chars.
    const int shift = 1075 - (biased_exp == 0 ? 1 : biased_exp);
    if (decimals < 0 || decimals > kFastDecimals || shift <= 0 || biased_exp == 0x7ff || last - first < kFastChars)
        return std::to_chars(first, last, value, std::chars_format::fixed, decimals);
    char* p = first;
    *p = '-';
    p += bits >> 63;   // kept only for a negative value (or -0.0)
    // Zeros first: most fields of the rows where a tool does not cut (two thirds of FORCES.csv's
    // numbers for the 10 s contour). Whatever the decimals, the first decimals + 2 of these.
    if ((bits << 1) == 0) {
        static_assert(kFastChars >= 1 + 16);
        std::memcpy(p, "0.00000000000000", 16);
        return {p + (decimals > 0 ? decimals + 2 : 1), std::errc()};
    }
    std::uint64_t mantissa = bits & ((std::uint64_t(1) << 52) - 1);
    if (biased_exp != 0) mantissa |= std::uint64_t(1) << 52;

    // The count of 10^-decimals units, |value| * 10^decimals rounded half to even, in integers:
    // the product is exact (under 2^83), so no rounding of a double product can move a tie.
    std::uint64_t units = 0;
    // Most values need no 128-bit arithmetic. Below 2^52 every half unit k + 1/2 is a double, and
    // rounding to nearest never steps over a double: the double product |value| * 10^decimals lies
    // on the same side of every half unit as the exact product, or on one. Off the half units it
    // therefore rounds to the same count; on one (a tie, or a value a rounding away from one) the
    // exact count below decides. (A float's value, 24 bits, times 10^5 or less is even exact.)
    const double scaled_d = std::fabs(value) * kPow10Double[decimals];
    if (scaled_d < 0x1p52) {
        const double whole_d = double(std::int64_t(scaled_d));   // truncation is floor here
        // Exact where it matters: scaled_d - whole_d is (Sterbenz), and so is the half taken off
        // it unless scaled_d < 1/4, where the difference is below -1/4 whatever its rounding.
        const double above_half = scaled_d - whole_d - 0.5;
        if (above_half != 0) {
            units = std::uint64_t(whole_d) + (above_half > 0 ? 1 : 0);
            goto write;
        }
    }
    if (shift < 84) {   // otherwise the product is below half a unit: 0
        const U128 scaled = U128(mantissa) * kPow10[decimals];
        const U128 whole = scaled >> shift;
        const U128 rest = scaled - (whole << shift);
        const U128 half = U128(1) << (shift - 1);
        const U128 rounded = whole + (rest > half || (rest == half && (whole & 1) != 0) ? 1 : 0);
        if (rounded >> 64 != 0) return std::to_chars(first, last, value, std::chars_format::fixed, decimals);
        units = std::uint64_t(rounded);
    }

write:
    switch (decimals) {
        case 0: p = put_units<0>(p, units); break;
        case 1: p = put_units<1>(p, units); break;
        case 2: p = put_units<2>(p, units); break;
        case 3: p = put_units<3>(p, units); break;
        case 4: p = put_units<4>(p, units); break;
        case 5: p = put_units<5>(p, units); break;
        case 6: p = put_units<6>(p, units); break;
        case 7: p = put_units<7>(p, units); break;
        case 8: p = put_units<8>(p, units); break;
        default: p = put_units<9>(p, units); break;
    }
    static_assert(kFastDecimals == 9);
    return {p, std::errc()};
}

}  // namespace cutload::textio
