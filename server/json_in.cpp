#include "json_in.hpp"

#include "textio/text.hpp"

#include <fmt/format.h>

#include <vector>

namespace cutload::server {
namespace {

// Builds the value as json::parse does, and keeps the path to the value being read so that an
// error can name its key.
class PathTrackingSax {
public:
    explicit PathTrackingSax(json& out) : dom_(out, false) {}

    bool null() { return value() && dom_.null(); }
    bool boolean(bool v) { return value() && dom_.boolean(v); }
    bool number_integer(json::number_integer_t v) { return value() && dom_.number_integer(v); }
    bool number_unsigned(json::number_unsigned_t v) { return value() && dom_.number_unsigned(v); }
    bool number_float(json::number_float_t v, const json::string_t& s) { return value() && dom_.number_float(v, s); }
    bool string(json::string_t& v) { return value() && dom_.string(v); }
    bool binary(json::binary_t& v) { return value() && dom_.binary(v); }
    bool start_object(std::size_t n) {
        if (!value()) return false;
        frames_.push_back({false, -1, ""});
        return dom_.start_object(n);
    }
    bool key(json::string_t& k) {
        frames_.back().key = k;
        return dom_.key(k);
    }
    bool end_object() {
        frames_.pop_back();
        return dom_.end_object();
    }
    bool start_array(std::size_t n) {
        if (!value()) return false;
        frames_.push_back({true, -1, ""});
        return dom_.start_array(n);
    }
    bool end_array() {
        frames_.pop_back();
        return dom_.end_array();
    }
    bool parse_error(std::size_t position, const std::string& token, const nlohmann::detail::exception& e) {
        failed_ = true;
        position_ = position;
        token_ = token;
        overflow_ = e.id == 406;
        message_ = e.what();
        // A number too large is refused before it is counted as an array's element.
        if (overflow_ && !frames_.empty() && frames_.back().array) ++frames_.back().index;
        return false;
    }

    // The path to the value being read: "tool.diameter_mm", "tests[2]"; "" at the top.
    std::string path() const {
        std::string p;
        for (const Frame& f : frames_) {
            if (f.array) {
                if (f.index >= 0) p += fmt::format("[{}]", f.index);
            } else if (!f.key.empty() || f.index >= 0) {
                p += (p.empty() ? "" : ".") + f.key;
            }
        }
        return p;
    }

    bool failed_ = false, overflow_ = false;
    std::size_t position_ = 0;
    std::string token_, message_;

private:
    struct Frame {
        bool array;
        long index;   // arrays: the element being read
        std::string key;
    };

    // A value starts: in an array it is the next element.
    bool value() {
        if (!frames_.empty() && frames_.back().array) ++frames_.back().index;
        return true;
    }

    nlohmann::detail::json_sax_dom_parser<json> dom_;
    std::vector<Frame> frames_;
};

}  // namespace

json error_body(const std::string& code, const std::string& message) {
    return json{{"error", {{"code", code}, {"message", textio::printable(message)}}}};
}

json parse_client_json(const std::string& text, const std::string& what, const std::string& code) {
    json out;
    PathTrackingSax sax(out);
    const bool ok = json::sax_parse(text, &sax);
    if (ok && !sax.failed_) return out;
    const std::string path = sax.path();
    const std::string at_key = path.empty() ? "" : fmt::format(", key {}", path);
    // The token is the client's text: shown printable (an invalid UTF-8 byte as an escape).
    const std::string token = textio::printable(sax.token_.substr(0, 40));
    if (sax.overflow_)
        throw ApiError(400, code,
                       fmt::format("{}: byte {}{}: the number {} is outside the range of a double (about 1.8e308)", what,
                                   sax.position_, at_key, token));
    throw ApiError(400, code, fmt::format("{} is not valid JSON: byte {}{}: {}", what, sax.position_, at_key,
                                          textio::printable(sax.message_)));
}

}  // namespace cutload::server
