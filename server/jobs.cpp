#include "jobs.hpp"

#include "program.hpp"
#include "db/jobs.hpp"
#include "db/runs.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <string_view>

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
    return in;
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

Jobs::Jobs(db::Store& store, JobPoolOptions opt, Metrics& metrics, std::vector<JobKind> kinds)
    : store_(store), opt_(opt), metrics_(metrics), kinds_(std::move(kinds)) {}

Jobs::~Jobs() { stop(0); }

void Jobs::start() {
    {
        auto s = store_.session();
        // Only one server owns the database (see the lock in Core), so 'running' here means the
        // previous process died mid-job: its results were never committed, so run it again.
        // One that was claimed max_attempts times has taken the server down that often: it fails
        // with the reason rather than looping.
        const int cap = std::max(1, opt_.max_attempts);
        for (const JobKind& k : kinds_) {
            const db::Requeued r = s->jobs().requeue_interrupted(
                k.queue, cap,
                fmt::format("interrupted {} times (the server died while computing it); not re-queued again "
                            "(attempt cap: cutload serve --max-attempts {})",
                            cap, cap),
                db::now_iso());
            if (r.requeued) spdlog::info("re-queued {} {} interrupted by the last shutdown", r.requeued, k.queue.name);
            if (r.failed)
                spdlog::warn("{} {} interrupted {} times failed (attempt cap)", r.failed, k.queue.name, cap);
        }
    }
    for (int i = 0; i < std::max(1, opt_.workers); ++i) threads_.emplace_back([this] { worker(); });
}

void Jobs::notify() {
    std::lock_guard lk(mu_);
    ++wake_seq_;
    cv_.notify_all();
}

bool Jobs::cancel_running(const db::JobQueue& queue, std::int64_t id) {
    std::lock_guard lk(mu_);
    auto it = running_.find({queue.name, id});
    if (it == running_.end()) return false;
    it->second->store(true);
    return true;
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
        if (stopping_ && threads_.empty()) return;
        stopping_ = true;
        cv_.notify_all();
        idle_cv_.wait_for(lk, std::chrono::duration<double>(drain_s), [this] { return running_.empty(); });
        requeue_on_cancel_ = true;
        for (auto& [id, flag] : running_) flag->store(true);
    }
    for (auto& t : threads_) t.join();
    threads_.clear();
}

// In registry order: runs first (an optimization re-predicts a finished run, a queued run is
// someone waiting).
std::optional<Jobs::Claimed> Jobs::claim() {
    auto s = store_.session();
    for (const JobKind& k : kinds_) {
        const auto id = k.claim ? k.claim(*s) : s->jobs().claim_oldest(k.queue, db::now_iso());
        if (id) return Claimed{&k, *id};
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
            if (job) running_[{job->kind->queue.name, job->id}] = flag;
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
    const JobKind& kind = *job.kind;
    const auto t_start = std::chrono::steady_clock::now();
    auto elapsed_s = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count(); };
    auto last_write = t_start - std::chrono::seconds(1);
    JobContext ctx{job.id, cancel, [&](double f) {
                       // At most a few writes per second: progress is for people polling, not an audit trail.
                       const auto now = std::chrono::steady_clock::now();
                       if (now - last_write < std::chrono::milliseconds(250)) return;
                       last_write = now;
                       store_.session()->jobs().set_progress(kind.queue, job.id, f);
                   }};
    auto finish = [&](db::JobState state, const std::optional<std::string>& error) {
        store_.session()->jobs().finish(kind.queue, job.id, state, error, db::now_iso());
    };
    try {
        const auto detail = kind.handler(ctx);
        if (!detail) {
            spdlog::info("{} {} was deleted while computing; nothing stored", kind.name, job.id);
            return;
        }
        metrics_.job_finished(kind.metrics, JobOutcome::Done, elapsed_s());
        spdlog::info("{} {} done in {:.2f} s{}", kind.name, job.id, elapsed_s(), *detail);
    } catch (const force_model::Cancelled&) {
        const bool requeue = requeue_on_cancel_.load();
        finish(requeue ? db::JobState::Queued : db::JobState::Cancelled, std::nullopt);
        metrics_.job_finished(kind.metrics, requeue ? JobOutcome::Requeued : JobOutcome::Cancelled, elapsed_s());
        spdlog::info("{} {} {}", kind.name, job.id, requeue ? "interrupted by shutdown, re-queued" : "cancelled");
    } catch (const std::exception& e) {
        finish(db::JobState::Failed, std::string(e.what()));
        metrics_.job_finished(kind.metrics, JobOutcome::Failed, elapsed_s());
        spdlog::warn("{} {} failed: {}", kind.name, job.id, e.what());
    }
}

}  // namespace cutload::server
