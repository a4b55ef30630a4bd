#include "textio/text.hpp"

#include <array>
#include <cstdint>
#include <cstring>

namespace cutload::textio {
namespace {

// Windows-1252 for 0x80-0x9F; 0 where it defines no character.
constexpr std::array<char32_t, 32> kCp1252High{
    0x20AC, 0,      0x201A, 0x0192, 0x201E, 0x2026, 0x2020, 0x2021, 0x02C6, 0x2030, 0x0160,
    0x2039, 0x0152, 0,      0x017D, 0,      0,      0x2018, 0x2019, 0x201C, 0x201D, 0x2022,
    0x2013, 0x2014, 0x02DC, 0x2122, 0x0161, 0x203A, 0x0153, 0,      0x017E, 0x0178};

void append_code_point(std::string& out, char32_t c) {
    if (c < 0x80) {
        out += static_cast<char>(c);
    } else if (c < 0x800) {
        out += static_cast<char>(0xC0 | (c >> 6));
        out += static_cast<char>(0x80 | (c & 0x3F));
    } else {
        out += static_cast<char>(0xE0 | (c >> 12));
        out += static_cast<char>(0x80 | ((c >> 6) & 0x3F));
        out += static_cast<char>(0x80 | (c & 0x3F));
    }
}

bool is_cont(unsigned char b) { return (b & 0xC0) == 0x80; }

// Length of the well-formed UTF-8 sequence starting at p (RFC 3629: no overlong forms, no
// surrogates, nothing above U+10FFFF), or 0 when there is none.
std::size_t utf8_sequence(const unsigned char* p, std::size_t left) {
    const unsigned char b = p[0];
    if (b < 0x80) return 1;
    if (b >= 0xC2 && b <= 0xDF) return left >= 2 && is_cont(p[1]) ? 2 : 0;
    if (b >= 0xE0 && b <= 0xEF) {
        if (left < 3 || !is_cont(p[1]) || !is_cont(p[2])) return 0;
        if (b == 0xE0 && p[1] < 0xA0) return 0;   // overlong
        if (b == 0xED && p[1] > 0x9F) return 0;   // surrogate
        return 3;
    }
    if (b >= 0xF0 && b <= 0xF4) {
        if (left < 4 || !is_cont(p[1]) || !is_cont(p[2]) || !is_cont(p[3])) return 0;
        if (b == 0xF0 && p[1] < 0x90) return 0;   // overlong
        if (b == 0xF4 && p[1] > 0x8F) return 0;   // above U+10FFFF
        return 4;
    }
    return 0;
}

}  // namespace

TextError::TextError(std::string source, std::size_t line, std::size_t column, const std::string& what)
    : std::runtime_error(place(source, line, column) + what), source_(std::move(source)), line_(line), column_(column) {}

std::string place(std::string_view source, std::size_t line, std::size_t column) {
    std::string s(source);
    if (line) s += ':' + std::to_string(line);
    if (line && column) s += ':' + std::to_string(column);
    return s + ": ";
}

std::string Refusal::why() const {
    static const char* hex = "0123456789ABCDEF";
    const std::string b = std::string("0x") + hex[byte >> 4] + hex[byte & 15];
    if (byte == 0) return "a NUL byte (0x00): binary data, not text";
    return "byte " + b + " is not a character (not UTF-8, and undefined in Windows-1252)";
}

bool is_ascii(std::string_view bytes) {
    // Eight bytes at a time: this runs over every line of every log.
    const char* p = bytes.data();
    std::size_t n = bytes.size();
    while (n >= 8) {
        std::uint64_t w;
        std::memcpy(&w, p, 8);
        if (w & 0x8080808080808080ULL) return false;
        p += 8;
        n -= 8;
    }
    for (; n; --n, ++p)
        if (static_cast<unsigned char>(*p) & 0x80) return false;
    return true;
}

std::optional<Refusal> append_utf8(std::string& out, std::string_view bytes) {
    const auto* p = reinterpret_cast<const unsigned char*>(bytes.data());
    const std::size_t n = bytes.size();
    std::size_t column = 1;
    for (std::size_t i = 0; i < n; ++column) {
        const unsigned char b = p[i];
        if (b == 0) return Refusal{i, column, b};
        if (const std::size_t len = utf8_sequence(p + i, n - i)) {
            out.append(bytes.data() + i, len);
            i += len;
            continue;
        }
        // Not UTF-8: one byte of the fallback code page.
        const char32_t c = b < 0xA0 ? kCp1252High[b - 0x80] : static_cast<char32_t>(b);
        if (c == 0) return Refusal{i, column, b};
        append_code_point(out, c);
        ++i;
    }
    return std::nullopt;
}

std::string decode(std::string_view bytes, std::string_view source) {
    if (is_ascii(bytes) && bytes.find('\0') == std::string_view::npos) return std::string(bytes);
    std::string out;
    out.reserve(bytes.size() + bytes.size() / 8);
    std::size_t line = 1, start = 0;
    while (start <= bytes.size()) {
        const std::size_t nl = bytes.find('\n', start);
        const std::size_t end = nl == std::string_view::npos ? bytes.size() : nl + 1;
        if (const auto r = append_utf8(out, bytes.substr(start, end - start)))
            throw TextError(std::string(source), line, r->column, r->why());
        if (nl == std::string_view::npos) break;
        start = end;
        ++line;
    }
    return out;
}

std::string printable(std::string_view bytes) {
    std::string out;
    while (!bytes.empty()) {
        const auto r = append_utf8(out, bytes);
        if (!r) break;
        static const char* hex = "0123456789ABCDEF";
        out += "\\x";
        out += hex[r->byte >> 4];
        out += hex[r->byte & 15];
        bytes.remove_prefix(r->byte_offset + 1);
    }
    return out;
}

std::string_view first_characters(std::string_view utf8, std::size_t n) {
    std::size_t chars = 0;
    for (std::size_t i = 0; i < utf8.size(); ++i)
        if (!is_cont(static_cast<unsigned char>(utf8[i])) && chars++ == n) return utf8.substr(0, i);
    return utf8;
}

std::size_t characters(std::string_view utf8) {
    std::size_t n = 0;
    for (const char c : utf8) n += !is_cont(static_cast<unsigned char>(c));
    return n;
}

}  // namespace cutload::textio
