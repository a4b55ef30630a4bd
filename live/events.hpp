// Private to live: making events, and the per-connection limit on reported warnings.
#pragma once

#include "live/live.hpp"

#include <optional>
#include <string>

namespace cutload::live {

inline SourceEvent make_event(EventKind kind, std::string message) {
    SourceEvent e;
    e.kind = kind;
    e.at = WallClock::now();
    e.message = std::move(message);
    return e;
}

// A stream of garbage must not become a stream of events: of the warnings counted in `count`
// (one connection's), the first 20 are reported, then one saying that the rest are not.
inline std::optional<SourceEvent> limited_warning(unsigned& count, const std::string& what) {
    constexpr unsigned kReported = 20;
    ++count;
    if (count <= kReported) return make_event(EventKind::Warning, what);
    if (count == kReported + 1) return make_event(EventKind::Warning, "more warnings on this connection are not reported");
    return std::nullopt;
}

}  // namespace cutload::live
