#include "http_guard.hpp"

#include <cctype>

namespace cutload::server {
namespace {

constexpr std::string_view kKeyPrefix = "clk_";
constexpr std::size_t kKeyHexDigits = 48;

bool iequals(std::string_view a, std::string_view b) {
    if (a.size() != b.size()) return false;
    for (std::size_t i = 0; i < a.size(); ++i)
        if (std::tolower(static_cast<unsigned char>(a[i])) != std::tolower(static_cast<unsigned char>(b[i]))) return false;
    return true;
}

bool is_port(std::string_view s) {
    if (s.empty() || s.size() > 5) return false;
    for (char c : s)
        if (c < '0' || c > '9') return false;
    return true;
}

}  // namespace

std::optional<std::string> bearer_token(std::string_view v, std::string* why) {
    constexpr std::string_view scheme = "Bearer ";
    if (v.size() < scheme.size() || !iequals(v.substr(0, scheme.size()), scheme)) {
        *why = "Authorization header must be 'Bearer <key>'";
        return std::nullopt;
    }
    const std::string_view token = v.substr(scheme.size());
    unsigned bad = token.size() == kKeyPrefix.size() + kKeyHexDigits ? 0u : 1u;
    for (std::size_t i = 0; i < token.size(); ++i) {
        const char c = token[i];
        const bool want = i < kKeyPrefix.size() ? c == kKeyPrefix[i] : (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f');
        bad |= want ? 0u : 1u;
    }
    if (bad) {
        *why = "malformed API key: a key is 'clk_' and 48 lowercase hex digits, with nothing before or after it";
        return std::nullopt;
    }
    return std::string(token);
}

bool is_loopback_host_header(std::string_view host) {
    std::string_view name = host;
    if (!host.empty() && host.front() == '[') {
        const auto close = host.find(']');
        if (close == std::string_view::npos) return false;
        name = host.substr(0, close + 1);
        const std::string_view rest = host.substr(close + 1);
        if (!rest.empty() && (rest.front() != ':' || !is_port(rest.substr(1)))) return false;
        return name == "[::1]";
    }
    if (const auto colon = host.find(':'); colon != std::string_view::npos) {
        if (!is_port(host.substr(colon + 1))) return false;
        name = host.substr(0, colon);
    }
    return iequals(name, "localhost") || name == "127.0.0.1";
}

bool is_loopback_peer(std::string_view addr) {
    return addr == "::1" || addr.rfind("127.", 0) == 0 || addr.rfind("::ffff:127.", 0) == 0;
}

}  // namespace cutload::server
