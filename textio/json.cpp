#include "textio/json.hpp"

#include <nlohmann/json.hpp>

#include <fstream>
#include <optional>
#include <vector>

namespace cutload::textio {
namespace {

using nlohmann::json;

// Builds the document as nlohmann's own DOM parser does, and knows at every moment which key it
// is reading: the JSON library's errors carry a byte offset only.
class Builder final : public nlohmann::json_sax<json> {
public:
    struct Failure {
        std::size_t byte = 0;   // where the library stopped (after the offending token)
        std::string token;      // the token as the library shows it
        int id = 0;             // the library's exception id (406: number out of range)
        std::string what;
    };

    json& root() { return root_; }
    const std::optional<Failure>& failure() const { return failure_; }
    bool too_deep() const { return too_deep_; }

    // "tool.holder.diameter_mm", "stock.box_mm.min[2]"; empty at the top level.
    std::string key_path() const {
        std::string path;
        for (const Frame& f : frames_) {
            if (f.container->is_array()) {
                path += '[' + std::to_string(f.container->size()) + ']';
            } else if (f.has_key) {
                if (!path.empty()) path += '.';
                path += f.key;
            }
        }
        return path;
    }

    bool null() override { return put(nullptr); }
    bool boolean(bool v) override { return put(v); }
    bool number_integer(number_integer_t v) override { return put(v); }
    bool number_unsigned(number_unsigned_t v) override { return put(v); }
    bool number_float(number_float_t v, const string_t&) override { return put(v); }
    bool string(string_t& v) override { return put(std::move(v)); }
    bool binary(binary_t& v) override { return put(json::binary(std::move(v))); }
    bool start_object(std::size_t) override { return open(json::object()); }
    bool key(string_t& k) override {
        frames_.back().key = std::move(k);
        frames_.back().has_key = true;
        return true;
    }
    bool end_object() override { return close(); }
    bool start_array(std::size_t) override { return open(json::array()); }
    bool end_array() override { return close(); }
    bool parse_error(std::size_t byte, const std::string& token, const nlohmann::detail::exception& e) override {
        failure_ = Failure{byte, token, e.id, e.what()};
        return false;
    }

private:
    struct Frame {
        json* container = nullptr;
        std::string key;   // objects: the key whose value is being read
        bool has_key = false;
    };

    // Where the next value goes. Containers on the stack never move while they are open: only the
    // innermost one grows, and its parent does not change until it is closed.
    json& slot() {
        if (frames_.empty()) return root_;
        Frame& f = frames_.back();
        if (f.container->is_array()) {
            f.container->push_back(nullptr);
            return f.container->back();
        }
        return (*f.container)[f.key];   // a repeated key keeps its last value, as nlohmann's parser does
    }
    bool put(json v) {
        slot() = std::move(v);
        after_value();
        return true;
    }
    bool open(json empty) {
        if (frames_.size() >= kMaxJsonDepth) {
            too_deep_ = true;
            return false;
        }
        json& s = slot();
        s = std::move(empty);
        frames_.push_back(Frame{&s, {}, false});
        return true;
    }
    bool close() {
        frames_.pop_back();
        after_value();
        return true;
    }
    // A finished value inside an object ends its key: an error before the next key is at the
    // object, not at the last key read. (Array paths count elements, so they need nothing.)
    void after_value() {
        if (!frames_.empty() && frames_.back().container->is_object()) frames_.back().has_key = false;
    }

    json root_;
    std::vector<Frame> frames_;
    std::optional<Failure> failure_;
    bool too_deep_ = false;
};

// 1-based line and character column of byte `offset` of the UTF-8 `text`.
std::pair<std::size_t, std::size_t> line_column(std::string_view text, std::size_t offset) {
    offset = std::min(offset, text.size());
    const std::string_view before = text.substr(0, offset);
    const std::size_t nl = before.rfind('\n');
    std::size_t line = 1;
    for (const char c : before) line += c == '\n';
    const std::string_view in_line = nl == std::string_view::npos ? before : before.substr(nl + 1);
    return {line, characters(in_line) + 1};
}

// The library's message without its own prefix and place ("[json.exception.parse_error.101]
// parse error at line 1, column 9: "), which ours replace.
std::string library_detail(const std::string& what) {
    std::string s = what;
    if (const auto bracket = s.find("] "); s.rfind("[json.exception.", 0) == 0 && bracket != std::string::npos)
        s = s.substr(bracket + 2);
    if (const auto col = s.find(", column "); col != std::string::npos)
        if (const auto colon = s.find(": ", col); colon != std::string::npos) s = s.substr(colon + 2);
    if (s.rfind("parse error: ", 0) == 0) s = s.substr(13);
    return printable(s);
}

}  // namespace

JsonError::JsonError(std::string source, std::size_t line, std::size_t column, std::string key, const std::string& why)
    : TextError(std::move(source), line, column, key.empty() ? why : key + ": " + why), key_(std::move(key)) {}

json parse_json(std::string_view bytes, std::string_view source) {
    const std::string text = decode(bytes, source);   // TextError names line and column of a refused byte
    Builder b;
    if (json::sax_parse(text, &b, json::input_format_t::json, /*strict=*/true)) return std::move(b.root());
    const std::string key = b.key_path();
    if (b.too_deep())
        throw JsonError(std::string(source), 0, 0, key,
                        "nested deeper than " + std::to_string(kMaxJsonDepth) + " levels (objects and arrays)");
    if (!b.failure()) throw JsonError(std::string(source), 0, 0, key, "not valid JSON");
    const auto& f = *b.failure();
    if (f.id == 406) {
        // A number too large for a double: point at its first digit.
        const std::size_t start = f.byte >= f.token.size() ? f.byte - f.token.size() : 0;
        const auto [line, column] = line_column(text, start);
        throw JsonError(std::string(source), line, column, key,
                        "the number " + printable(f.token) +
                            " is out of range (a number must lie within about -1.8e308 to 1.8e308)");
    }
    const auto [line, column] = line_column(text, f.byte > 0 ? f.byte - 1 : 0);
    throw JsonError(std::string(source), line, column, key, "not valid JSON: " + library_detail(f.what));
}

json read_json_file(const std::string& path, std::string_view what) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw JsonError(path, 0, 0, "", "cannot open the " + std::string(what));
    std::string text;
    char buf[1 << 16];
    while (in.read(buf, sizeof buf) || in.gcount() > 0) {
        text.append(buf, static_cast<std::size_t>(in.gcount()));
        if (text.size() > kMaxJsonFileBytes)
            throw JsonError(path, 0, 0, "",
                            "the " + std::string(what) + " is larger than " +
                                std::to_string(kMaxJsonFileBytes >> 20) + " MiB: not a hand-written JSON file");
    }
    if (in.bad()) throw JsonError(path, 0, 0, "", "cannot read the " + std::string(what));
    return parse_json(text, path);
}

}  // namespace cutload::textio
