// The form-shaping code of document 000 (eqs. 3.25-3.26, after Inasaki et al. 1997), read into the
// same chain as the explicit form.
#include "json_reader.hpp"

#include <fmt/format.h>

#include <cctype>
#include <string>

namespace cutload::machine {

std::vector<Axis> parse_form_shaping_code(const std::string& code, const std::string& path) {
    using detail::fail;
    // Table 3.1: 1/2/3 translate along X/Y/Z, 4/5/6 rotate about X/Y/Z.
    static const std::string kDigitAxes = "XYZABC";
    std::vector<Axis> chain;
    bool seen_bed = false, seen_tool = false;
    std::size_t symbols = 0;
    for (std::size_t pos = 0; pos < code.size(); ++pos) {
        const char c = code[pos];
        if (std::isspace(static_cast<unsigned char>(c))) continue;
        const std::string where = fmt::format("'{}' at position {}", c, pos + 1);
        if (seen_tool) fail(path, fmt::format("{} follows the tool 't', which must come last", where));
        ++symbols;
        if (c == 'w') {
            if (symbols != 1) fail(path, fmt::format("{}: the workpiece 'w' must come first", where));
            continue;
        }
        if (c == 't') {
            seen_tool = true;
            continue;
        }
        if (c == 'b') {
            if (seen_bed) fail(path, fmt::format("{}: the bed 'b' appears twice", where));
            seen_bed = true;
            continue;
        }
        char name = 0;
        if (c >= '1' && c <= '6') name = kDigitAxes[static_cast<std::size_t>(c - '1')];
        if (kDigitAxes.find(c) != std::string::npos) name = c;
        if (name == 0)
            fail(path, fmt::format("{}: expected an axis letter X Y Z A B C, a motion digit 1-6, or w, b, t", where));
        for (const Axis& a : chain)
            if (a.name == name) fail(path, fmt::format("{}: axis {} appears twice", where, name));
        Axis a;
        a.name = name;
        const int k = static_cast<int>(kDigitAxes.find(name));
        a.type = k < 3 ? AxisType::Linear : AxisType::Rotary;
        a.direction = Eigen::Vector3d::Unit(k % 3);
        a.side = seen_bed ? Side::Tool : Side::Workpiece;
        a.channel = std::string(1, static_cast<char>(std::tolower(static_cast<unsigned char>(name))));
        chain.push_back(a);
    }
    if (!seen_bed)
        fail(path, "has no bed 'b': put it between the axes that move the workpiece and those that move the tool "
                   "(\"C A b Y X Z t\": a C table on an A trunnion, X, Y, Z in the head)");
    if (chain.empty()) fail(path, "names no axes");
    return chain;
}

}  // namespace cutload::machine
