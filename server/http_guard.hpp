// Internal to server: what the service decides from a request's headers alone, before any body is
// read: the bearer token, whether a Host header names this machine.
#pragma once

#include <optional>
#include <string>
#include <string_view>

namespace cutload::server {

// The key in an Authorization header value, or nullopt with *why set. Exactly "Bearer " (scheme in
// any case, one space) and a token of the form keys have ("clk_" + 48 lowercase hex digits):
// trailing bytes, an embedded NUL, whitespace or any other byte are refused, so no key is
// matched by a prefix of what was sent. The check reads every byte whatever it finds (no early
// exit), and the key is then found by its SHA-256, so timing tells nothing about a stored key.
std::optional<std::string> bearer_token(std::string_view header_value, std::string* why);

// Whether a Host header value names the loopback interface: localhost, 127.0.0.1 or [::1], each
// with or without a port. A browser sends the name it was pointed at, so a page from another
// origin that a DNS name was rebound to 127.0.0.1 still says its own name here.
bool is_loopback_host_header(std::string_view host);

// Whether a connection's peer address is on the loopback interface (127/8, ::1, ::ffff:127/104).
bool is_loopback_peer(std::string_view addr);

}  // namespace cutload::server
