// Shared pieces of the live sources (live/live.hpp).
#include "live/live.hpp"

#include "live/agent_client.hpp"
#include "live/shdr_client.hpp"

#include <fmt/format.h>

#include <charconv>

namespace cutload::live {

const char* to_string(EventKind kind) {
    switch (kind) {
        case EventKind::Connected: return "connected";
        case EventKind::Disconnected: return "disconnected";
        case EventKind::ConnectFailed: return "connect_failed";
        case EventKind::Gap: return "gap";
        case EventKind::Restarted: return "restarted";
        case EventKind::Warning: return "warning";
    }
    return "unknown";
}

std::chrono::milliseconds Backoff::delay(unsigned failures) const {
    std::chrono::milliseconds d = initial;
    for (unsigned i = 1; i < failures && d < max; ++i) d *= 2;
    return std::min(d, max);
}

HostPort parse_host_port(const std::string& text, int default_port) {
    std::string h = text;
    std::string p;
    if (!h.empty() && h.front() == '[') {
        const auto close = h.find(']');
        if (close == std::string::npos) throw SourceError(fmt::format("'{}': unclosed '[' in address", text));
        p = h.substr(close + 1);
        h = h.substr(1, close - 1);
        if (!p.empty() && p.front() != ':') throw SourceError(fmt::format("'{}': expected ':' after ']'", text));
        if (!p.empty()) p.erase(0, 1);
    } else if (const auto colon = h.rfind(':'); colon != std::string::npos) {
        p = h.substr(colon + 1);
        h = h.substr(0, colon);
    }
    if (h.empty()) throw SourceError(fmt::format("'{}': no host (expected HOST:PORT)", text));
    if (p.empty()) {
        if (default_port < 0) throw SourceError(fmt::format("'{}': no port (expected HOST:PORT)", text));
        return {h, default_port};
    }
    int v = -1;
    const auto [end, ec] = std::from_chars(p.data(), p.data() + p.size(), v);
    if (ec != std::errc() || end != p.data() + p.size() || v < 0 || v > 65535)
        throw SourceError(fmt::format("'{}': '{}' is not a port (0..65535)", text, p));
    return {h, v};
}

std::unique_ptr<Source> open_source(const std::string& url) {
    if (url.rfind("shdr://", 0) == 0) {
        ShdrOptions opt;
        std::string rest = url.substr(7);
        while (!rest.empty() && rest.back() == '/') rest.pop_back();
        const HostPort hp = parse_host_port(rest, 7878);
        opt.host = hp.host;
        opt.port = hp.port;
        return std::make_unique<ShdrSource>(std::move(opt));
    }
    if (url.rfind("http://", 0) == 0 || url.rfind("https://", 0) == 0) {
        AgentOptions opt;
        const auto host_start = url.find("://") + 3;
        const auto slash = url.find('/', host_start);
        std::string path = slash == std::string::npos ? "" : url.substr(slash);
        while (!path.empty() && path.back() == '/') path.pop_back();
        const auto last = path.rfind('/');
        if (last != std::string::npos && last + 1 < path.size()) {
            opt.device = path.substr(last + 1);
            path.erase(last);
        }
        opt.base_url = url.substr(0, slash) + path;
        return std::make_unique<AgentSource>(std::move(opt));
    }
    throw SourceError(fmt::format("source '{}': expected shdr://HOST[:PORT] or http://HOST[:PORT]/DEVICE", url));
}

}  // namespace cutload::live
