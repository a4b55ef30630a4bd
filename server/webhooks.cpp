#include "webhooks.hpp"

#include <arpa/inet.h>
#include <fmt/format.h>
#include <httplib.h>
#include <netdb.h>
#include <netinet/in.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <cmath>
#include <cstring>
#include <regex>

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

std::string refused_address(const sockaddr* a) {
    char text[INET6_ADDRSTRLEN] = "";
    if (a->sa_family == AF_INET) {
        const auto* in = reinterpret_cast<const sockaddr_in*>(a);
        const std::uint32_t ip = ntohl(in->sin_addr.s_addr);
        inet_ntop(AF_INET, &in->sin_addr, text, sizeof text);
        if ((ip >> 16) == 0xA9FE) return fmt::format("{} is a link-local address (cloud metadata services answer there)", text);
        if (ip == 0) return fmt::format("{} is the unspecified address", text);
        if ((ip >> 28) == 0xE) return fmt::format("{} is a multicast address", text);
    } else if (a->sa_family == AF_INET6) {
        const auto* in6 = reinterpret_cast<const sockaddr_in6*>(a);
        const in6_addr& x = in6->sin6_addr;
        inet_ntop(AF_INET6, &x, text, sizeof text);
        if (IN6_IS_ADDR_LINKLOCAL(&x)) return fmt::format("{} is a link-local address", text);
        if (IN6_IS_ADDR_UNSPECIFIED(&x)) return fmt::format("{} is the unspecified address", text);
        if (IN6_IS_ADDR_MULTICAST(&x)) return fmt::format("{} is a multicast address", text);
        if (IN6_IS_ADDR_V4MAPPED(&x)) {
            sockaddr_in v4{};
            v4.sin_family = AF_INET;
            std::memcpy(&v4.sin_addr, x.s6_addr + 12, 4);
            return refused_address(reinterpret_cast<const sockaddr*>(&v4));
        }
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

Webhooks::Webhooks(DbPool& pool, const ServerOptions& opt, Metrics& metrics)
    : pool_(pool), opt_(opt), metrics_(metrics) {}

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
    struct Due {
        std::int64_t id;
        std::string url, secret, payload;
        int attempts;
    };
    std::vector<Due> due;
    {
        auto c = pool_.get();
        auto st = c->prepare(
            "SELECT d.id, w.url, w.secret, d.payload, d.attempts FROM webhook_deliveries d "
            "JOIN webhooks w ON w.id = d.webhook_id WHERE d.state = 'pending' AND d.next_attempt_unix <= ? "
            "ORDER BY d.next_attempt_unix LIMIT 32");
        st.bind(1, unix_now_s());
        while (st.step())
            due.push_back({st.i64(0), st.text(1), st.opt_text(2).value_or(""), st.text(3), static_cast<int>(st.i64(4))});
    }
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
            if (!d.secret.empty()) h.emplace("X-Cutload-Signature", "sha256=" + hmac_sha256_hex(d.secret, d.payload));
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

        const int attempt = d.attempts + 1;
        const bool give_up = !ok && attempt >= opt_.webhook_max_attempts;
        const double next = unix_now_s() + opt_.webhook_backoff_s * std::pow(2.0, attempt - 1);
        auto c = pool_.get();
        db::Transaction tx(*c);
        auto log = c->prepare(
            "INSERT INTO webhook_attempts(delivery_id, attempt, at, status, error, duration_ms) VALUES (?,?,?,?,?,?)");
        log.bind(1, d.id).bind(2, attempt).bind(3, db::now_iso());
        if (status)
            log.bind(4, status);
        else
            log.bind_null(4);
        if (ok)
            log.bind_null(5);
        else
            log.bind(5, error);
        log.bind(6, ms).run();
        auto up = c->prepare(
            "UPDATE webhook_deliveries SET attempts = ?, state = ?, next_attempt_unix = ?, delivered_at = ? WHERE id = ?");
        up.bind(1, attempt).bind(2, ok ? "delivered" : give_up ? "failed" : "pending").bind(3, next);
        if (ok)
            up.bind(4, db::now_iso());
        else
            up.bind_null(4);
        up.bind(5, d.id).run();
        tx.commit();
        if (!ok) spdlog::warn("webhook delivery {} attempt {} to {}: {}", d.id, attempt, d.url, error);
    }
    auto c = pool_.get();
    auto st = c->prepare("SELECT min(next_attempt_unix) FROM webhook_deliveries WHERE state = 'pending'");
    if (st.step() && !st.is_null(0)) return st.real(0) - unix_now_s();
    return 1;
}

}  // namespace cutload::server
