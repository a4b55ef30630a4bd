// format_fixed against std::to_chars (fixed, with a precision): the same characters for every
// value and every number of decimals, ties, signs and the values it hands to std::to_chars included.
#include "textio/number.hpp"

#include <catch2/catch.hpp>

#include <bit>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <string>

using namespace cutload::textio;

namespace {

std::string reference(double v, int decimals) {
    char buf[400];
    const auto r = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::fixed, decimals);
    REQUIRE(r.ec == std::errc());
    return std::string(buf, r.ptr);
}

std::string fast(double v, int decimals) {
    char buf[400];
    const auto r = format_fixed(buf, buf + sizeof buf, v, decimals);
    REQUIRE(r.ec == std::errc());
    return std::string(buf, r.ptr);
}

// Counts the mismatches (and shows the first few) rather than stopping at one.
int mismatches(double v, int first_decimals = 0, int last_decimals = 12) {
    int bad = 0;
    for (int d = first_decimals; d <= last_decimals; ++d)
        if (fast(v, d) != reference(v, d)) {
            if (++bad <= 3) UNSCOPED_INFO("value " << std::bit_cast<std::uint64_t>(v) << " decimals " << d << ": "
                                                   << fast(v, d) << " != " << reference(v, d));
        }
    return bad;
}

}  // namespace

TEST_CASE("format_fixed: special and boundary values print as std::to_chars prints them") {
    const double inf = std::numeric_limits<double>::infinity();
    const double values[] = {0.0, -0.0, 1.0, -1.0, 0.5, -0.5, 1.5, 2.5, 0.0005, 0.0015, 0.0025, -0.0025, 0.0625,
                             1.0625, 0.1, 0.2, 0.3, 1e-300, -1e-300, 5e-324, -5e-324, 2.2250738585072014e-308,
                             4503599627370495.5, 4503599627370496.0, -4503599627370495.5, 9007199254740993.0, 1e19,
                             1.8446744073709552e19, 1e22, 1e300, -1e308, std::numeric_limits<double>::max(), inf, -inf,
                             std::numeric_limits<double>::quiet_NaN(), -std::numeric_limits<double>::quiet_NaN(),
                             123456.7890125, 99.9995, 99.99949999999999, 0.9999999995, 9.5, 10.5, 0.045, 1e-9, 5e-10,
                             -5e-10, 1.5e-9, 2.5e-9, 18446744073.709551615, 1844674407370.9551615};
    for (double v : values) CHECK(mismatches(v, 0, 17) == 0);
}

TEST_CASE("format_fixed: exact ties round half to even as std::to_chars does") {
    // k / 2^j with j <= 9 holds a tie at every number of decimals below j.
    std::mt19937_64 rng(20261128);
    int bad = 0;
    for (int i = 0; i < 200000; ++i) {
        const double v = double(std::int64_t(rng() % 20000001) - 10000000) / double(1 << (rng() % 12));
        bad += mismatches(v, 0, 10);
    }
    CHECK(bad == 0);
}

TEST_CASE("format_fixed: random values of every magnitude print as std::to_chars prints them") {
    std::mt19937_64 rng(14);
    int bad = 0;
    // Any bit pattern (NaNs, infinities, subnormals, huge values: most go to std::to_chars).
    for (int i = 0; i < 20000; ++i) bad += mismatches(std::bit_cast<double>(rng()), 0, 12);
    // What result files hold: forces, angles, times, lengths, from 1e-12 to 1e16.
    std::uniform_real_distribution<double> mantissa(-10.0, 10.0);
    for (int i = 0; i < 300000; ++i) {
        const double v = mantissa(rng) * std::pow(10.0, int(rng() % 29) - 13);
        bad += mismatches(v, 0, 10);
    }
    // Values a ulp or two either side of a half unit: k.5 / 10^d nudged.
    for (int i = 0; i < 200000; ++i) {
        const int d = int(rng() % 10);
        const double tie = (double(rng() % 100000000) + 0.5) / std::pow(10.0, d);
        const double v = std::nextafter(tie, (rng() & 1) != 0 ? 1e300 : -1e300);
        bad += mismatches(v, d, d) + mismatches(tie, d, d) + mismatches(-v, d, d);
    }
    CHECK(bad == 0);
}

TEST_CASE("format_fixed: a short buffer fails as std::to_chars does") {
    char buf[8];
    const auto r = format_fixed(buf, buf + sizeof buf, 123456.789, 3);   // 10 characters
    const auto ref = std::to_chars(buf, buf + sizeof buf, 123456.789, std::chars_format::fixed, 3);
    CHECK(r.ec == ref.ec);
    CHECK(r.ec == std::errc::value_too_large);
    const auto fits = format_fixed(buf, buf + sizeof buf, 1.5, 3);
    REQUIRE(fits.ec == std::errc());
    CHECK(std::string(buf, fits.ptr) == "1.500");
}

TEST_CASE("format_fixed: float results and values within a rounding of a half unit print as std::to_chars prints them") {
    // FORCES.csv's force, torque and length columns are floats: their double product with 10^d
    // is exact up to d = 5, and the fast path takes almost all of them.
    std::mt19937_64 rng(20261129);
    std::uniform_real_distribution<float> force(-3000.0f, 3000.0f);
    int bad = 0;
    for (int i = 0; i < 200000; ++i) bad += mismatches(double(force(rng)), 0, 9);
    // Half units that no double product can tell apart from its neighbours: k + 1/2 over 10^d,
    // nudged by up to 64 ulps either way, at magnitudes up to 2^50 units (where the product's
    // rounding is largest against its fraction).
    for (int i = 0; i < 200000; ++i) {
        const int d = int(rng() % 10);
        const double units = double(rng() % (std::uint64_t(1) << (10 + rng() % 41))) + 0.5;
        double v = units / std::pow(10.0, d);
        const int nudge = int(rng() % 129) - 64;
        for (int k = 0; k < std::abs(nudge); ++k) v = std::nextafter(v, nudge > 0 ? 1e300 : -1e300);
        bad += mismatches(v, d, d) + mismatches(-v, d, d);
    }
    CHECK(bad == 0);
}
