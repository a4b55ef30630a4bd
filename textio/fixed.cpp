#include "textio/number.hpp"

#include <bit>
#include <cstdint>
#include <cstring>

namespace cutload::textio {
namespace {

__extension__ typedef unsigned __int128 U128;   // m * 10^9 needs 83 bits

constexpr int kFastDecimals = 9;
constexpr std::uint64_t kPow10[kFastDecimals + 1] = {1,         10,         100,         1000,         10000,
                                                     100000,    1000000,    10000000,    100000000,    1000000000};

}  // namespace

std::to_chars_result format_fixed(char* first, char* last, double value, int decimals) {
    // The longest fast result: "-", 20 digits of a 64-bit quotient, ".", no more: 22 characters.
    constexpr std::ptrdiff_t kFastChars = 24;
    const std::uint64_t bits = std::bit_cast<std::uint64_t>(value);
    const int biased_exp = int(bits >> 52 & 0x7ff);
    // |value| = mantissa / 2^shift exactly; shift <= 0 (|value| >= 2^52), NaN and infinities are
    // left to std::to_chars.
    const int shift = 1075 - (biased_exp == 0 ? 1 : biased_exp);
    if (decimals < 0 || decimals > kFastDecimals || shift <= 0 || biased_exp == 0x7ff || last - first < kFastChars)
        return std::to_chars(first, last, value, std::chars_format::fixed, decimals);
    std::uint64_t mantissa = bits & ((std::uint64_t(1) << 52) - 1);
    if (biased_exp != 0) mantissa |= std::uint64_t(1) << 52;

    // The count of 10^-decimals units, |value| * 10^decimals rounded half to even, in integers:
    // the product is exact (under 2^83), so no rounding of a double product can move a tie.
    std::uint64_t units = 0;
    if (shift < 84) {   // otherwise the product is below half a unit: 0
        const U128 scaled = U128(mantissa) * kPow10[decimals];
        const U128 whole = scaled >> shift;
        const U128 rest = scaled - (whole << shift);
        const U128 half = U128(1) << (shift - 1);
        const U128 rounded = whole + (rest > half || (rest == half && (whole & 1) != 0) ? 1 : 0);
        if (rounded >> 64 != 0) return std::to_chars(first, last, value, std::chars_format::fixed, decimals);
        units = std::uint64_t(rounded);
    }

    // Digits from the last one back: the decimals (zero padded), the point, the integer part.
    // They end kFastChars into `text`, so that a copy of a constant kFastChars bytes (two vector
    // moves, not a call to memcpy) takes them and stays inside it.
    char text[2 * kFastChars];
    char* p = text + kFastChars;
    for (int i = 0; i < decimals; ++i) {
        *--p = char('0' + units % 10);
        units /= 10;
    }
    if (decimals > 0) *--p = '.';
    do {
        *--p = char('0' + units % 10);
        units /= 10;
    } while (units != 0);
    if (bits >> 63 != 0) *--p = '-';
    std::memcpy(first, p, kFastChars);
    return {first + (text + kFastChars - p), std::errc()};
}

}  // namespace cutload::textio
