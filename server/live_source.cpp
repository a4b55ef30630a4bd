#include "live_source.hpp"

#include "core.hpp"

#include "live/live.hpp"

#include <fmt/format.h>

namespace cutload::server {

std::string live_source_address(const json& src, const std::string& key) {
    if (src.is_string()) {
        const std::string s = src.get<std::string>();
        try {
            (void)live::open_source(s);   // checks the address; opening connects nothing yet
        } catch (const live::SourceError& e) {
            throw ApiError(400, "bad_request", fmt::format("{}: {}", key, e.what()));
        }
        return s;
    }
    if (!src.is_object()) throw ApiError(400, "bad_request", key + ": must be an address or an object with adapter or agent");
    if (src.contains("adapter")) {
        if (!src["adapter"].is_string()) throw ApiError(400, "bad_request", key + ".adapter: must be HOST:PORT");
        try {
            const live::HostPort hp = live::parse_host_port(src["adapter"].get<std::string>(), 7878);
            // An IPv6 literal is bracketed so the port stays apart from it.
            const bool v6 = hp.host.find(':') != std::string::npos;
            return fmt::format("shdr://{}{}{}:{}", v6 ? "[" : "", hp.host, v6 ? "]" : "", hp.port);
        } catch (const live::SourceError& e) {
            throw ApiError(400, "bad_request", fmt::format("{}.adapter: {}", key, e.what()));
        }
    }
    if (src.contains("agent")) {
        if (!src["agent"].is_string()) throw ApiError(400, "bad_request", key + ".agent: must be the agent's URL");
        std::string url = src["agent"].get<std::string>();
        if (src.contains("device")) {
            if (!src["device"].is_string() || src["device"].get<std::string>().empty())
                throw ApiError(400, "bad_request", key + ".device: must be the device's name");
            while (!url.empty() && url.back() == '/') url.pop_back();
            url.push_back('/');
            url += src["device"].get<std::string>();
        }
        if (url.rfind("http://", 0) != 0 && url.rfind("https://", 0) != 0)
            throw ApiError(400, "bad_request", key + ".agent: must start with http:// or https://");
        return url;
    }
    throw ApiError(400, "bad_request", key + ": give adapter (HOST:PORT) or agent (URL) and device");
}

}  // namespace cutload::server
