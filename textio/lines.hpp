// Physical lines of a text stream, in bounded memory: a line longer than the limit is an error
// naming it (a binary file or a missing line break must not grow a buffer without end). Line
// ends are "\n" or "\r\n"; a UTF-8 byte order mark before line 1 is dropped. text() decodes
// the line to UTF-8 (text.hpp) or throws naming its line and column; raw() gives the bytes.
#pragma once

#include "textio/text.hpp"

#include <cstddef>
#include <istream>
#include <string>
#include <string_view>
#include <vector>

namespace cutload::textio {

inline constexpr std::size_t kDefaultMaxLineBytes = std::size_t{1} << 20;   // 1 MiB

class LineReader {
public:
    LineReader(std::istream& in, std::string source, std::size_t max_line_bytes = kDefaultMaxLineBytes);

    // The next line; false at the end of the input. Throws TextError for an overlong line.
    bool next();
    std::size_t number() const { return number_; }      // 1-based line number
    std::string_view raw() const { return raw_; }         // bytes, without the line end
    std::string_view text();                             // UTF-8 (decoded once per line)
    bool ascii();                                        // the line is plain ASCII
    const std::string& source() const { return source_; }
    std::size_t max_line_bytes() const { return max_; }

    [[noreturn]] void fail(std::size_t column, const std::string& what) const;   // at this line

private:
    bool fill();

    std::istream& in_;
    std::string source_;
    std::size_t max_;
    std::vector<char> buf_;
    std::size_t begin_ = 0, end_ = 0;   // unread bytes in buf_
    bool eof_ = false;
    std::size_t number_ = 0;
    std::string_view raw_;
    std::string decoded_;
    int state_ = 0;   // 0: not decoded yet, 1: ASCII (text is raw), 2: decoded_ holds the text
};

}  // namespace cutload::textio
