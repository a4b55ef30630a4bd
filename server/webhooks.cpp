#include "webhooks.hpp"

#include "db/alerts.hpp"

#include <arpa/inet.h>
#include <fmt/format.h>
#include <httplib.h>
#include <netdb.h>
#include <netinet/in.h>
#include <spdlog/spdlog.h>

#include <array>
#include <chrono>
#include <cstdint>
#include <cmath>
#include <cstring>
#include <regex>
#include <vector>

namespace cutload::server {

bool split_http_url(const std::string& url, std::string* origin, std::string* path, std::string* host) {
    static const std::regex re(R"(^(https?://([A-Za-z0-9.\-]+)|https?://\[([0-9A-Fa-f:.]+)\])(:[0-9]{1,5})?(/[^\s#]*)?$)");
    std::smatch m;
    if (!std::regex_match(url, m, re)) return false;
    *origin = m[1].str() + m[4].str();
    *path = m[5].matched ? m[5].str() : "/";
    if (host) *host = m[2].matched ? m[2].str() : m[3].str();
    return true;
}

namespace {

std::string refused_v4(const std::uint8_t* b) {
    const std::uint32_t ip = (std::uint32_t{b[0]} << 24) | (std::uint32_t{b[1]} << 16) | (std::uint32_t{b[2]} << 8) | b[3];
    const std::string text = fmt::format("{}.{}.{}.{}", b[0], b[1], b[2], b[3]);
    if ((ip >> 16) == 0xA9FE) return fmt::format("{} is a link-local address (cloud metadata services answer there)", text);
    if (ip == 0) return fmt::format("{} is the unspecified address", text);
    if ((ip >> 28) == 0xE) return fmt::format("{} is a multicast address", text);
    return "";
}

// The IPv4 addresses an IPv6 address carries, by the forms that route (or translate) to them:
// v4-mapped ::ffff:a.b.c.d, v4-compatible ::a.b.c.d, SIIT-translated ::ffff:0:a.b.c.d, NAT64
// 64:ff9b::/96 and the local-use 64:ff9b:1::/48 (RFC 8215, /96 layout), 6to4 2002:AABB:CCDD::/16,
// Teredo 2001:0::/32 (server, and the client XOR 0xff) and ISATAP interface ids (::[02]00:5efe:a.b.c.d).
std::vector<std::array<std::uint8_t, 4>> embedded_v4(const std::uint8_t* x) {
    std::vector<std::array<std::uint8_t, 4>> out;
    auto at = [&](int i, std::uint8_t mask = 0) {
        out.push_back({static_cast<std::uint8_t>(x[i] ^ mask), static_cast<std::uint8_t>(x[i + 1] ^ mask),
                       static_cast<std::uint8_t>(x[i + 2] ^ mask), static_cast<std::uint8_t>(x[i + 3] ^ mask)});
    };
    auto zero = [&](int from, int to) {
        for (int i = from; i < to; ++i)
            if (x[i] != 0) return false;
        return true;
    };
    const bool last32_nonzero = !zero(12, 16);
    if (zero(0, 10) && x[10] == 0xff && x[11] == 0xff) at(12);                            // ::ffff:a.b.c.d
    if (zero(0, 12) && last32_nonzero) at(12);                                            // ::a.b.c.d (::1 is 0.0.0.1)
    if (zero(0, 8) && x[8] == 0xff && x[9] == 0xff && zero(10, 12)) at(12);               // ::ffff:0:a.b.c.d
    if (x[0] == 0x00 && x[1] == 0x64 && x[2] == 0xff && x[3] == 0x9b) at(12);             // 64:ff9b::/96, 64:ff9b:1::/48
    if (x[0] == 0x20 && x[1] == 0x02) at(2);                                              // 6to4
    if (x[0] == 0x20 && x[1] == 0x01 && x[2] == 0x00 && x[3] == 0x00) {                   // Teredo
        at(4);
        at(12, 0xff);
    }
    if ((x[8] & 0xfd) == 0x00 && x[9] == 0x00 && x[10] == 0x5e && x[11] == 0xfe) at(12);  // ISATAP
    return out;
}

std::string refused_address(const sockaddr* a) {
    char text[INET6_ADDRSTRLEN] = "";
    if (a->sa_family == AF_INET) {
        const auto* in = reinterpret_cast<const sockaddr_in*>(a);
        return refused_v4(reinterpret_cast<const std::uint8_t*>(&in->sin_addr.s_addr));
    } else if (a->sa_family == AF_INET6) {
        const auto* in6 = reinterpret_cast<const sockaddr_in6*>(a);
        const in6_addr& x = in6->sin6_addr;
        inet_ntop(AF_INET6, &x, text, sizeof text);
        if (IN6_IS_ADDR_LINKLOCAL(&x)) return fmt::format("{} is a link-local address", text);
        if (IN6_IS_ADDR_UNSPECIFIED(&x)) return fmt::format("{} is the unspecified address", text);
        if (IN6_IS_ADDR_MULTICAST(&x)) return fmt::format("{} is a multicast address", text);
        // An address that carries an IPv4 address reaches it (through the host's stack, a NAT64
        // gateway or a tunnel): it is refused as that IPv4 address would be.
        for (const auto& v4 : embedded_v4(x.s6_addr))
            if (std::string why = refused_v4(v4.data()); !why.empty())
                return fmt::format("{} carries the IPv4 address {}.{}.{}.{}: {}", text, v4[0], v4[1], v4[2], v4[3], why);
    }
    return "";
}

}  // namespace

std::string refused_webhook_host(const std::string& host, bool resolve) {
    addrinfo hints{};
    hints.ai_socktype = SOCK_STREAM;
    hints.ai_flags = resolve ? 0 : AI_NUMERICHOST;
    addrinfo* found = nullptr;
    if (getaddrinfo(host.c_str(), nullptr, &hints, &found) != 0) return "";   // not a literal, or unknown: the POST says so
    std::string why;
    for (const addrinfo* a = found; a && why.empty(); a = a->ai_next) why = refused_address(a->ai_addr);
    freeaddrinfo(found);
    if (!why.empty() && why.rfind(host, 0) != 0) why = host + " resolves to " + why;
    return why;
}

Webhooks::Webhooks(db::Store& store, const ServerOptions& opt, Metrics& metrics)
    : store_(store), opt_(opt), metrics_(metrics) {}

Webhooks::~Webhooks() { stop(); }

void Webhooks::start() { thread_ = std::thread([this] { loop(); }); }

void Webhooks::notify() {
    std::lock_guard lk(mu_);
    poked_ = true;
    cv_.notify_all();
}

void Webhooks::stop() {
    {
        std::lock_guard lk(mu_);
        stopping_ = true;
        cv_.notify_all();
    }
    if (thread_.joinable()) thread_.join();
}

void Webhooks::loop() {
    for (;;) {
        double wait_s = 1;
        try {
            wait_s = deliver_due();
        } catch (const std::exception& e) {
            spdlog::error("webhooks: {}", e.what());
        }
        std::unique_lock lk(mu_);
        cv_.wait_for(lk, std::chrono::duration<double>(std::clamp(wait_s, 0.01, 1.0)),
                     [this] { return stopping_ || poked_; });
        if (stopping_) return;
        poked_ = false;
    }
}

double Webhooks::deliver_due() {
    const std::vector<db::DueDelivery> due = store_.session()->webhooks().due(unix_now_s(), 32);
    for (const auto& d : due) {
        {
            std::lock_guard lk(mu_);
            if (stopping_) return 1;
        }
        std::string origin, path, host, error;
        int status = 0;
        const auto t0 = std::chrono::steady_clock::now();
        if (!split_http_url(d.url, &origin, &path, &host)) {
            error = "not an http(s) URL";
        } else if (std::string why = refused_webhook_host(host, true); !why.empty()) {
            error = "refused: " + why;
        } else {
            httplib::Client cli(origin);
            const auto timeout = std::chrono::duration<double>(opt_.webhook_timeout_s);
            cli.set_connection_timeout(std::chrono::duration_cast<std::chrono::microseconds>(timeout));
            cli.set_read_timeout(std::chrono::duration_cast<std::chrono::microseconds>(timeout));
            cli.set_write_timeout(std::chrono::duration_cast<std::chrono::microseconds>(timeout));
            httplib::Headers h{{"User-Agent", "cutload-webhook/1"}, {"X-Cutload-Delivery", std::to_string(d.id)}};
            const std::string secret = d.secret.value_or("");
            if (!secret.empty()) h.emplace("X-Cutload-Signature", "sha256=" + hmac_sha256_hex(secret, d.payload));
            auto res = cli.Post(path, h, d.payload, "application/json");
            if (!res)
                error = httplib::to_string(res.error());
            else
                status = res->status;
        }
        const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
        const bool ok = status >= 200 && status < 300;
        if (!ok && error.empty()) error = "HTTP " + std::to_string(status);
        metrics_.webhook_attempt(ok);

        const std::int64_t attempt = d.attempts + 1;
        const bool give_up = !ok && attempt >= opt_.webhook_max_attempts;
        const double next = unix_now_s() + opt_.webhook_backoff_s * std::pow(2.0, static_cast<double>(attempt - 1));
        const std::string now = db::now_iso();
        db::DeliveryAttempt a{attempt, now, status ? std::optional<std::int64_t>(status) : std::nullopt,
                              ok ? std::nullopt : std::optional<std::string>(error), ms};
        const auto state = ok ? db::DeliveryState::Delivered : give_up ? db::DeliveryState::Failed : db::DeliveryState::Pending;
        store_.session()->webhooks().record_attempt(d.id, a, state, next, ok ? std::optional<std::string>(now) : std::nullopt);
        if (!ok) spdlog::warn("webhook delivery {} attempt {} to {}: {}", d.id, attempt, d.url, error);
    }
    if (const auto next = store_.session()->webhooks().next_pending_unix()) return *next - unix_now_s();
    return 1;
}

}  // namespace cutload::server
