#include "jobs.hpp"
#include "freed_memory.hpp"

#include "program.hpp"
#include "db/jobs.hpp"
#include "db/runs.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <random>
#include <string_view>

#include <unistd.h>

namespace cutload::server {
namespace fs = std::filesystem;

app::RunInput run_input(const json& inputs, const fs::path& upload_dir, bool use_opencl) {
    const json& log = inputs.at("log");
    app::LogFormat format;
    format.format = log.value("format", "auto");
    if (log.contains("mapping") && log["mapping"].is_string())
        format.map_file = (upload_dir / log["mapping"].get<std::string>()).string();
    if (log.contains("mapping_preset") && log["mapping_preset"].is_string()) format.map_file = log["mapping_preset"].get<std::string>();
    if (log.contains("units") && log["units"].is_string()) format.length_unit = log["units"].get<std::string>();
    if (log.contains("feed_units") && log["feed_units"].is_string()) format.feed_unit = log["feed_units"].get<std::string>();
    app::RunInput in;
    in.log_path = (upload_dir / log.at("stored_as").get<std::string>()).string();
    in.read = app::read_options(format);
    in.spec = force_model::parse_run_spec(inputs.at("spec"));
    if (inputs.contains("nc_program")) in.program = program_source(inputs.at("nc_program"), upload_dir);
    in.device = app::choose_device(use_opencl ? "opencl" : "cpu").device;
    if (inputs.contains("kinematics")) {
        const json& k = inputs.at("kinematics");
        in.machine = app::load_machine_definition(kinematics_files(upload_dir, k));
        in.tool_length_mm = k.value("tool_length_mm", 0.0);
    }
    return in;
}

app::MachineFiles kinematics_files(const fs::path& upload_dir, const json& kinematics) {
    app::MachineFiles f;
    f.path = (upload_dir / kinematics.at("stored_as").get<std::string>()).string();
    f.shown_as = "part kinematics";
    if (kinematics.contains("errors")) {
        f.errors_path = (upload_dir / kinematics["errors"].get<std::string>()).string();
        f.errors_shown_as = "part kinematics_errors";
    }
    return f;
}

app::WorkLimits work_limits(const ServerOptions& opt) {
    app::WorkLimits w;
    w.max_force_rows = opt.max_force_rows;
    w.max_stock_cells = opt.max_stock_cells;
    w.max_job_memory_mb = opt.max_job_memory_mb;
    return w;
}

force_model::StockPtr load_base_stock(db::Store& store, std::optional<std::int64_t> base_run) {
    if (!base_run) return nullptr;
    force_model::StockPtr stock;
    // Read in place: the bytes are the store's until the call returns.
    const bool found = store.session()->runs().read_final_stock(*base_run, [&](std::span<const unsigned char> bytes) {
        stock = force_model::load_stock_bytes(std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()),
                                              fmt::format("base_run {} stock", *base_run));
    });
    if (!found) throw std::runtime_error(fmt::format("base_run {}: its final stock is gone (run deleted?)", *base_run));
    return stock;
}

namespace {

// Names this process's claims in the store: readable in a query (which host, which pid) and
// unique across restarts of one pid.
std::string make_token_prefix() {
    char host[256] = {};
    if (::gethostname(host, sizeof host - 1) != 0) std::snprintf(host, sizeof host, "unknown-host");
    std::random_device rd;
    return fmt::format("{}:{}:{:08x}/", host, static_cast<long>(::getpid()), rd());
}

}  // namespace

Jobs::Jobs(db::Store& store, JobPoolOptions opt, Metrics& metrics, std::vector<JobKind> kinds)
    : store_(store), opt_(opt), metrics_(metrics), kinds_(std::move(kinds)), token_prefix_(make_token_prefix()) {}

Jobs::~Jobs() { stop(0); }

void Jobs::requeue(bool expired_only) {
    auto s = store_.session();
    const int cap = std::max(1, opt_.max_attempts);
    const std::string error = fmt::format(
        "interrupted {} times (the process computing it died: {}); not re-queued again (attempt cap: --max-attempts {})",
        cap, expired_only ? "its lease ended" : "the server restarted", cap);
    const std::string now = db::now_iso();
    int requeued = 0;
    for (const JobKind& k : kinds_) {
        const db::Requeued r = expired_only ? s->jobs().requeue_expired(k.queue, cap, error, now)
                                            : s->jobs().requeue_interrupted(k.queue, cap, error, now);
        if (r.requeued)
            spdlog::info("re-queued {} {} {}", r.requeued, k.queue.name,
                         expired_only ? "whose lease ended (their process died or stalled)" : "interrupted by the last shutdown");
        if (r.failed) spdlog::warn("{} {} interrupted {} times failed (attempt cap)", r.failed, k.queue.name, cap);
        requeued += r.requeued;
    }
    if (requeued) notify();
}

void Jobs::start() {
    // On a store this server owns, 'running' means the previous process died mid-job: its
    // results were never committed, so run it again. On a shared store only an ended lease says so.
    requeue(opt_.shared_store);
    for (int i = 0; i < std::max(0, opt_.workers); ++i) threads_.emplace_back([this] { worker(); });
    if (opt_.shared_store) keeper_ = std::thread([this] { keeper(); });
    if (opt_.shared_store && opt_.workers > 0) listener_ = std::thread([this] { listener(); });
}

void Jobs::listener() {
    std::unique_ptr<db::JobSignal> signal;
    try {
        signal = store_.job_signal();
    } catch (const std::exception& e) {
        spdlog::warn("job signals: {}; idle workers look at the queue every 2 s instead", e.what());
    }
    if (!signal) return;
    for (;;) {
        {
            std::lock_guard lk(mu_);
            if (stopping_) return;
        }
        // A second at most between looks at stopping_.
        if (signal->wait(1.0)) notify();
    }
}

std::string Jobs::lease_until() const {
    return db::iso_time(std::chrono::system_clock::now() + std::chrono::duration_cast<std::chrono::system_clock::duration>(
                                                              std::chrono::duration<double>(opt_.lease_s)));
}

db::Lease Jobs::next_lease() { return {fmt::format("{}{}", token_prefix_, ++claims_), lease_until()}; }

void Jobs::keeper() {
    const auto period = std::chrono::duration<double>(std::max(0.05, opt_.lease_s / 3));
    auto wait = period;
    for (;;) {
        {
            // Renewing on through a stop's drain: the jobs finishing then are still this process's.
            std::unique_lock lk(mu_);
            if (cv_.wait_for(lk, wait, [this] { return workers_joined_; })) return;
        }
        wait = period;
        try {
            {
                // Under the lock claims register under: a job claimed after the renewal read the
                // store cannot be taken for one whose claim is gone.
                std::lock_guard lk(mu_);
                if (!running_.empty()) {
                    const std::string until = lease_until();
                    auto s = store_.session();
                    for (const JobKind& k : kinds_) {
                        const std::vector<std::int64_t> held = s->jobs().renew_leases(k.queue, token_prefix_, until);
                        for (auto& [key, job] : running_) {
                            if (key.first != k.queue.name || job.lost) continue;
                            if (std::find(held.begin(), held.end(), key.second) != held.end()) {
                                job.misses = 0;
                                continue;
                            }
                            // Twice in a row: a job this process has just stored is no longer
                            // 'running' for the moment before its worker lets go of it.
                            if (++job.misses < 2) continue;
                            job.lost = true;
                            job.cancel->store(true);
                            spdlog::warn("{} {}: this process no longer holds its claim (cancelled, deleted or re-queued "
                                         "elsewhere); stopping it",
                                         k.name, key.second);
                        }
                    }
                }
            }
            requeue(true);
        } catch (const std::exception& e) {
            // The store is unreachable: its leases cannot be kept either way. Look again in a few
            // seconds rather than at every period (each look is a new connection attempt).
            spdlog::error("job leases: {}", e.what());
            wait = std::max(period, std::chrono::duration<double>(5));
        }
    }
}

void Jobs::notify() {
    std::lock_guard lk(mu_);
    ++wake_seq_;
    cv_.notify_all();
}

bool Jobs::cancel_running(const db::JobQueue& queue, std::int64_t id) {
    {
        std::lock_guard lk(mu_);
        auto it = running_.find({queue.name, id});
        if (it != running_.end()) {
            it->second.cancel->store(true);
            return true;
        }
    }
    // Another process computes it: cancelled in the store, that process stops at its next renewal.
    return opt_.shared_store && store_.session()->jobs().cancel_running(queue, id, db::now_iso());
}

bool Jobs::wait_released(const db::JobQueue& queue, std::int64_t id, double timeout_s) {
    std::unique_lock lk(mu_);
    return idle_cv_.wait_for(lk, std::chrono::duration<double>(timeout_s),
                             [&] { return !running_.contains({queue.name, id}); });
}

long Jobs::running() const {
    std::lock_guard lk(mu_);
    return static_cast<long>(running_.size());
}

void Jobs::stop(double drain_s) {
    {
        std::unique_lock lk(mu_);
        if (stopping_ && threads_.empty() && !keeper_.joinable() && !listener_.joinable()) return;
        stopping_ = true;
        cv_.notify_all();
        idle_cv_.wait_for(lk, std::chrono::duration<double>(drain_s), [this] { return running_.empty(); });
        requeue_on_cancel_ = true;
        for (auto& [id, job] : running_) job.cancel->store(true);
    }
    for (auto& t : threads_) t.join();
    threads_.clear();
    {
        std::lock_guard lk(mu_);
        workers_joined_ = true;
    }
    cv_.notify_all();
    if (keeper_.joinable()) keeper_.join();
    if (listener_.joinable()) listener_.join();
}

// In registry order: runs first (an optimization re-predicts a finished run, a queued run is
// someone waiting).
std::optional<Jobs::Claimed> Jobs::claim() {
    auto s = store_.session();
    for (const JobKind& k : kinds_) {
        const db::Lease lease = next_lease();
        const auto id = k.claim ? k.claim(*s, lease) : s->jobs().claim_oldest(k.queue, db::now_iso(), lease);
        if (id) return Claimed{&k, *id, lease.token};
    }
    return std::nullopt;
}

void Jobs::worker() {
    for (;;) {
        std::optional<Claimed> job;
        std::uint64_t seq = 0;
        {
            std::unique_lock lk(mu_);
            if (stopping_) return;
            seq = wake_seq_;
        }
        auto flag = std::make_shared<std::atomic<bool>>(false);
        {
            // Claimed and registered under one lock: a cancel never sees a job 'running' that no
            // worker has registered yet.
            std::lock_guard lk(mu_);
            try {
                job = claim();
            } catch (const db::Error& e) {
                spdlog::error("job queue: {}", e.what());
            }
            if (job) running_[{job->kind->queue.name, job->id}] = Running{flag};
        }
        if (!job) {
            std::unique_lock lk(mu_);
            cv_.wait_for(lk, std::chrono::seconds(2), [this, seq] { return stopping_ || wake_seq_ != seq; });
            continue;
        }
        run(*job, *flag);
        {
            std::lock_guard lk(mu_);
            running_.erase({job->kind->queue.name, job->id});
        }
        idle_cv_.notify_all();
    }
}

void Jobs::run(const Claimed& job, const std::atomic<bool>& cancel) {
    const ReleaseFreedMemoryOnExit release_freed_memory;   // a run's motion model and stocks
    const JobKind& kind = *job.kind;
    const auto t_start = std::chrono::steady_clock::now();
    auto elapsed_s = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count(); };
    auto last_write = t_start - std::chrono::seconds(1);
    JobContext ctx{job.id, job.token, cancel, [&](double f) {
                       // At most a few writes per second: progress is for people polling, not an audit trail.
                       const auto now = std::chrono::steady_clock::now();
                       if (now - last_write < std::chrono::milliseconds(250)) return;
                       last_write = now;
                       store_.session()->jobs().set_progress(kind.queue, job.id, f);
                   }};
    auto finish = [&](db::JobState state, const std::optional<std::string>& error) {
        store_.session()->jobs().finish(kind.queue, job.id, state, error, db::now_iso(), job.token);
    };
    auto lost = [&] {
        std::lock_guard lk(mu_);
        auto it = running_.find({kind.queue.name, job.id});
        return it != running_.end() && it->second.lost;
    };
    try {
        const auto detail = kind.handler(ctx);
        if (!detail) {
            spdlog::info("{} {}: no longer held by this claim (deleted, cancelled or re-queued meanwhile); nothing stored",
                         kind.name, job.id);
            return;
        }
        metrics_.job_finished(kind.metrics, JobOutcome::Done, elapsed_s());
        spdlog::info("{} {} done in {:.2f} s{}", kind.name, job.id, elapsed_s(), *detail);
    } catch (const force_model::Cancelled&) {
        if (lost()) {
            spdlog::info("{} {} stopped: its claim is gone; nothing stored", kind.name, job.id);
            return;
        }
        const bool requeue = requeue_on_cancel_.load();
        finish(requeue ? db::JobState::Queued : db::JobState::Cancelled, std::nullopt);
        metrics_.job_finished(kind.metrics, requeue ? JobOutcome::Requeued : JobOutcome::Cancelled, elapsed_s());
        spdlog::info("{} {} {}", kind.name, job.id, requeue ? "interrupted by shutdown, re-queued" : "cancelled");
    } catch (const std::exception& e) {
        if (lost()) {
            spdlog::info("{} {} stopped ({}): its claim is gone; nothing stored", kind.name, job.id, e.what());
            return;
        }
        finish(db::JobState::Failed, std::string(e.what()));
        metrics_.job_finished(kind.metrics, JobOutcome::Failed, elapsed_s());
        spdlog::warn("{} {} failed: {}", kind.name, job.id, e.what());
    }
}

}  // namespace cutload::server
