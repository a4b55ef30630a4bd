// The backend-neutral half of the store: the session pool, the choice of backend by location,
// stored times, and the text of job and delivery states.
#include "db/store.hpp"

#include "db/alerts.hpp"
#include "db/jobs.hpp"
#include "schema.hpp"
#include "sqlite/store.hpp"

#include <fmt/format.h>

#include <array>
#include <ctime>

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

std::unique_ptr<Store> Store::open(const std::string& location, Open mode) {
    const auto scheme_end = location.find("://");
    if (scheme_end != std::string::npos) {
        const std::string scheme = location.substr(0, scheme_end);
        if (scheme == "postgresql" || scheme == "postgres")
            throw std::invalid_argument(
                fmt::format("{}: PostgreSQL is not supported yet; give the path of an SQLite database file", location));
        throw std::invalid_argument(fmt::format("{}: unknown database scheme '{}'; give the path of an SQLite database file",
                                                location, scheme));
    }
    return sqlite::open_store(location, mode == Open::MustExist);
}

int schema_version() { return kSchemaVersion; }

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

}  // namespace cutload::db
