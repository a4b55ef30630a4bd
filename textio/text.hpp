// Text as shops write it. Controller exports, dynamometer headers and NC comments arrive in
// whatever code page the PC that wrote them used: UTF-8 on new systems, Windows-1252 or Latin-1 on
// older ones (`Temperatur [°C]`, a block called `Fräsen N10`). Everything cutload echoes back
// (messages, reports, JSON bodies, CSV outputs) must be valid UTF-8, so every byte sequence read
// is either decoded or refused with its place (docs/formats.md, "Text encoding"):
//
//   - a well-formed UTF-8 sequence is kept as it is;
//   - any other byte is one character of the fallback: Windows-1252 for 0x80-0x9F (where it puts
//     the euro sign, typographic quotes and dashes), Latin-1 for 0xA0-0xFF (cp1252 agrees there);
//   - refused: NUL (binary data, not text) and the five bytes Windows-1252 leaves undefined
//     (0x81, 0x8D, 0x8F, 0x90, 0x9D).
//
// The choice is made per byte sequence, so a UTF-8 file with one Latin-1 line reads correctly.
// Latin-1 text that happens to form valid UTF-8 (e.g. "Ã¤") is read as UTF-8; real text almost
// never does.
#pragma once

#include <cstddef>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>

namespace cutload::textio {

// A text problem at a place: the message reads "source:line:column: what" (line and column
// 1-based; a 0 leaves that part out). Readers rethrow it as their own error type.
class TextError : public std::runtime_error {
public:
    TextError(std::string source, std::size_t line, std::size_t column, const std::string& what);
    const std::string& source() const { return source_; }
    std::size_t line() const { return line_; }
    std::size_t column() const { return column_; }

private:
    std::string source_;
    std::size_t line_ = 0, column_ = 0;
};

// "source:line:column: " (parts that are 0 left out), the prefix every reader's messages use.
std::string place(std::string_view source, std::size_t line, std::size_t column = 0);

// A byte that is not text under the rules above.
struct Refusal {
    std::size_t byte_offset = 0;   // in the input
    std::size_t column = 0;        // 1-based character column (characters decoded before it + 1)
    unsigned char byte = 0;
    std::string why() const;       // e.g. "byte 0x81 is not a character (not UTF-8, undefined in Windows-1252)"
};

// True when every byte is below 0x80: such text needs no decoding and its columns are bytes.
bool is_ascii(std::string_view bytes);

// Appends `bytes` to `out` as UTF-8. Returns the first refused byte (out then holds what came before).
std::optional<Refusal> append_utf8(std::string& out, std::string_view bytes);

// The whole text decoded; throws TextError naming source, line and column of a refused byte.
std::string decode(std::string_view bytes, std::string_view source);

// Always valid UTF-8, for echoing raw bytes in a message: decoded, a refused byte shown as \xNN.
std::string printable(std::string_view bytes);

// Number of characters (UTF-8 code points) in valid UTF-8 text.
std::size_t characters(std::string_view utf8);

// The first `n` characters of valid UTF-8 text (all of it when shorter), never a part of one:
// for quoting a line in a message without cutting a character in two.
std::string_view first_characters(std::string_view utf8, std::size_t n);

}  // namespace cutload::textio
