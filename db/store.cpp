// The backend-neutral half of the store: the session pool, the choice of backend by location,
// stored times, and the text of job and delivery states.
#include "db/store.hpp"

#include "db/alerts.hpp"
#include "db/jobs.hpp"
#include "schema.hpp"
#include "postgres/store.hpp"
#include "sqlite/store.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <ctime>
#include <stdexcept>

namespace cutload::db {

SessionLease::~SessionLease() {
    if (s_) store_->give_back(std::move(s_));
}

SessionLease Store::session() {
    {
        std::lock_guard lk(mu_);
        if (!idle_.empty()) {
            auto s = std::move(idle_.back());
            idle_.pop_back();
            return SessionLease(*this, std::move(s));
        }
    }
    return SessionLease(*this, connect());
}

void Store::give_back(std::unique_ptr<Session> s) {
    std::lock_guard lk(mu_);
    idle_.push_back(std::move(s));
}

Backend backend_of(const std::string& location) {
    const auto scheme_end = location.find("://");
    if (scheme_end == std::string::npos) return Backend::Sqlite;
    const std::string scheme = location.substr(0, scheme_end);
    if (scheme == "postgresql" || scheme == "postgres") return Backend::Postgres;
    throw std::invalid_argument(
        fmt::format("{}: unknown database scheme '{}'; give the path of an SQLite database file or a postgresql:// URL",
                    printable_location(location), scheme));
}

std::unique_ptr<Store> Store::open(const std::string& location, Open mode) {
    if (backend_of(location) == Backend::Postgres) return postgres::open_store(location, mode == Open::MustExist);
    return sqlite::open_store(location, mode == Open::MustExist);
}

int schema_version() { return kSchemaVersion; }

std::string printable_location(const std::string& location) {
    const auto scheme_end = location.find("://");
    if (scheme_end == std::string::npos) return location;
    std::string out = location;
    // user:password@ in the authority (before the first '/' after the scheme).
    const auto auth_begin = scheme_end + 3;
    const auto auth_end = std::min(out.find('/', auth_begin), out.size());
    const auto at = out.rfind('@', auth_end);
    if (at != std::string::npos && at >= auth_begin) {
        const auto colon = out.find(':', auth_begin);
        if (colon != std::string::npos && colon < at) out.replace(colon + 1, at - colon - 1, "***");
    }
    // password=... among the query parameters.
    for (auto p = out.find("password="); p != std::string::npos; p = out.find("password=", p + 1)) {
        if (p > 0 && out[p - 1] != '?' && out[p - 1] != '&') continue;
        const auto v = p + 9;
        const auto end = std::min(out.find('&', v), out.size());
        out.replace(v, end - v, "***");
    }
    return out;
}

std::string iso_time(std::chrono::system_clock::time_point t) {
    using namespace std::chrono;
    const auto ms = duration_cast<milliseconds>(t.time_since_epoch()).count() % 1000;
    const std::time_t secs = system_clock::to_time_t(t);
    std::tm tm{};
    gmtime_r(&secs, &tm);
    char buf[32];
    std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%S", &tm);
    return fmt::format("{}.{:03}Z", buf, ms);
}

std::string now_iso() { return iso_time(std::chrono::system_clock::now()); }

namespace {

constexpr std::array<std::string_view, 5> kJobStateText{"queued", "running", "done", "failed", "cancelled"};
constexpr std::array<std::string_view, 3> kDeliveryStateText{"pending", "delivered", "failed"};

}  // namespace

std::string_view to_text(JobState s) { return kJobStateText[static_cast<std::size_t>(s)]; }

std::optional<JobState> parse_job_state(std::string_view text) {
    for (std::size_t i = 0; i < kJobStateText.size(); ++i)
        if (kJobStateText[i] == text) return static_cast<JobState>(i);
    return std::nullopt;
}

JobState job_state_from_text(std::string_view text) {
    if (auto s = parse_job_state(text)) return *s;
    throw std::invalid_argument(fmt::format("'{}' is not a job state", text));
}

const std::vector<JobState>& job_states() {
    static const std::vector<JobState> all{JobState::Queued, JobState::Running, JobState::Done, JobState::Failed,
                                           JobState::Cancelled};
    return all;
}

std::string_view to_text(DeliveryState s) { return kDeliveryStateText[static_cast<std::size_t>(s)]; }

DeliveryState delivery_state_from_text(std::string_view text) {
    for (std::size_t i = 0; i < kDeliveryStateText.size(); ++i)
        if (kDeliveryStateText[i] == text) return static_cast<DeliveryState>(i);
    throw std::invalid_argument(fmt::format("'{}' is not a delivery state", text));
}

std::string_view job_table(const JobQueue& q) {
    const bool plain = !q.name.empty() && q.name.find_first_not_of("abcdefghijklmnopqrstuvwxyz_0123456789") == std::string_view::npos;
    if (!plain) throw std::logic_error(fmt::format("job queue '{}' is not a table name", q.name));
    return q.name;
}

}  // namespace cutload::db
