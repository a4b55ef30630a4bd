// Internal to server: the connection layer under httplib's request handling.
//
// httplib gives each connection a pool thread from accept to close, reading the request line and
// headers with a time-out per read only: a client that sends one header line every few seconds
// holds a thread for as long as it likes, and a few dozen such clients hold them all (/healthz
// included). Here a connection gets a request thread only once its whole header block has
// arrived: one gate thread reads every waiting connection's header bytes without blocking, under
// a deadline for the whole header block and a cap on the number of waiting connections; idle
// keep-alive connections wait in the gate too, not on a thread. A request thread then runs
// httplib's own request processing (parsing, routing, handlers, the response) on the buffered
// bytes, with a deadline for the body.
#pragma once

#include <httplib.h>

#include <cstddef>
#include <cstdint>
#include <memory>

namespace cutload::server {

struct GateLimits {
    double header_timeout_s = 10;        // request line + headers, from their first byte (408 beyond)
    double idle_timeout_s = 5;           // keep-alive: between requests (closed beyond)
    double read_timeout_s = 10;          // body: the longest wait for the next byte
    double body_timeout_s = 600;         // body: the whole of it
    std::size_t max_header_bytes = 64u << 10;   // request line + headers (431 beyond)
    int max_waiting = 512;               // connections waiting for headers or idle; beyond, the longest waiting is closed
    int threads = 64;                    // request threads
    std::size_t max_body_bytes = 256u << 20;    // a body (chunked framing aside) read no further than this
};

class GatedHttpServer : public httplib::Server {
public:
    GatedHttpServer();
    ~GatedHttpServer() override;
    // Before listening.
    void set_limits(const GateLimits& limits);

    struct Counters {
        long header_timeouts = 0;   // 408: headers not complete within header_timeout_s
        long header_too_large = 0;  // 431
        long evicted = 0;           // closed to keep max_waiting
    };
    Counters counters() const;

    // After binding: the listen backlog. Debian's httplib listens with a backlog of 5, so a burst of
    // connections (a page's parallel requests, a crowd of slow clients) overflows it and the
    // kernel makes the overflow retry their handshakes after 1, 2, 4... s, before the gate sees them.
    void widen_backlog(int connections);

    struct Impl;

private:
    bool process_and_close_socket(socket_t sock) override;
    std::shared_ptr<Impl> impl_;
};

// From a request handler (or a hook before the body is read): the request's body was not read,
// so the connection cannot carry another request. The response is sent with Connection: close,
// then the connection is drained for a moment (so the client reads the answer rather than a
// reset) and closed.
void close_after_response(const httplib::Request& req);

// A number that identifies the request now being processed on this thread (0 outside one): what a
// hook before the body decided can be kept for the handler of the same request.
std::uint64_t current_request_serial();

// Whether the request announces a body (Content-Length above 0, or chunked).
bool announces_body(const httplib::Request& req);

}  // namespace cutload::server
