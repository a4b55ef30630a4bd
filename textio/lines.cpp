#include "textio/lines.hpp"

#include <algorithm>
#include <cstring>

namespace cutload::textio {

LineReader::LineReader(std::istream& in, std::string source, std::size_t max_line_bytes)
    : in_(in), source_(std::move(source)), max_(max_line_bytes),
      // 64 KiB to start, grown to the line limit only for a line that needs it: a reader made for
      // a small file (an upload, a map, a fuzzer's input) must not allocate and zero 1 MiB.
      buf_(std::min<std::size_t>(max_line_bytes + 2, 1 << 16)) {}

// Moves the unread bytes to the front and reads more; false when nothing more came.
bool LineReader::fill() {
    if (eof_) return false;
    if (begin_ > 0) {
        std::memmove(buf_.data(), buf_.data() + begin_, end_ - begin_);
        end_ -= begin_;
        begin_ = 0;
    }
    if (end_ == buf_.size()) {
        const std::size_t cap = max_ + 2;   // a full line, its '\r' and the byte that proves it too long
        if (buf_.size() >= cap) return false;
        buf_.resize(std::min(cap, 2 * buf_.size()));
    }
    const std::streamsize got = in_.rdbuf() ? in_.rdbuf()->sgetn(buf_.data() + end_, static_cast<std::streamsize>(buf_.size() - end_)) : 0;
    if (got <= 0) {
        eof_ = true;
        return false;
    }
    end_ += static_cast<std::size_t>(got);
    return true;
}

bool LineReader::next() {
    state_ = 0;
    std::size_t scanned = 0;
    while (true) {
        const char* start = buf_.data() + begin_ + scanned;
        const void* nl = std::memchr(start, '\n', end_ - begin_ - scanned);
        if (nl) {
            const std::size_t len = static_cast<std::size_t>(static_cast<const char*>(nl) - (buf_.data() + begin_));
            raw_ = std::string_view(buf_.data() + begin_, len);
            begin_ += len + 1;
            break;
        }
        scanned = end_ - begin_;
        if (scanned > max_ + 1) {
            ++number_;
            fail(0, "line longer than " + std::to_string(max_) + " bytes (a binary file, or a file without line breaks?)");
        }
        if (!fill()) {
            if (end_ == begin_) return false;
            if (end_ - begin_ > max_ + 1) {
                ++number_;
                fail(0, "line longer than " + std::to_string(max_) + " bytes");
            }
            raw_ = std::string_view(buf_.data() + begin_, end_ - begin_);   // last line without a line end
            begin_ = end_;
            break;
        }
    }
    ++number_;
    if (!raw_.empty() && raw_.back() == '\r') raw_.remove_suffix(1);
    if (number_ == 1 && raw_.substr(0, 3) == "\xEF\xBB\xBF") raw_.remove_prefix(3);
    if (raw_.size() > max_) fail(0, "line longer than " + std::to_string(max_) + " bytes");
    return true;
}

bool LineReader::ascii() {
    (void)text();
    return state_ == 1;
}

std::string_view LineReader::text() {
    if (state_ == 0) {
        if (is_ascii(raw_) && std::memchr(raw_.data(), '\0', raw_.size()) == nullptr) {
            state_ = 1;
        } else {
            decoded_.clear();
            if (const auto r = append_utf8(decoded_, raw_)) fail(r->column, r->why());
            state_ = 2;
        }
    }
    return state_ == 1 ? raw_ : std::string_view(decoded_);
}

void LineReader::fail(std::size_t column, const std::string& what) const { throw TextError(source_, number_, column, what); }

}  // namespace cutload::textio
