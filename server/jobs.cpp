#include "jobs.hpp"

#include "program.hpp"
#include "results.hpp"
#include "db/jobs.hpp"
#include "db/runs.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <string_view>

namespace cutload::server {
namespace fs = std::filesystem;

namespace {

const db::JobQueue& queue_of(Jobs::Kind kind) { return kind == Jobs::Kind::Run ? db::kRunQueue : db::kOptimizationQueue; }

}  // namespace

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

Jobs::Jobs(db::Store& store, const ServerOptions& opt, fs::path data_dir, Metrics& metrics,
           std::function<void()> on_alerts)
    : store_(store), opt_(opt), data_dir_(std::move(data_dir)), metrics_(metrics), on_alerts_(std::move(on_alerts)) {}

Jobs::~Jobs() { stop(0); }

void Jobs::start() {
    {
        auto s = store_.session();
        // Only one server owns the database (see the lock in Core), so 'running' here means the
        // previous process died mid-job: its results were never committed, so run it again.
        for (const Kind kind : {Kind::Run, Kind::Optimization})
            if (int n = s->jobs().requeue_interrupted(queue_of(kind)))
                spdlog::info("re-queued {} {} interrupted by the last shutdown", n, queue_of(kind).name);
    }
    for (int i = 0; i < std::max(1, opt_.workers); ++i) threads_.emplace_back([this] { worker(); });
}

void Jobs::notify() {
    std::lock_guard lk(mu_);
    ++wake_seq_;
    cv_.notify_all();
}

bool Jobs::cancel_running(Kind kind, std::int64_t id) {
    std::lock_guard lk(mu_);
    auto it = running_.find({kind, id});
    if (it == running_.end()) return false;
    it->second->store(true);
    return true;
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

// Runs first: an optimization re-predicts a finished run, a queued run is someone waiting.
std::optional<Jobs::Job> Jobs::claim() {
    auto s = store_.session();
    for (const Kind kind : {Kind::Run, Kind::Optimization})
        if (const auto id = s->jobs().claim_oldest(queue_of(kind), db::now_iso())) return Job{kind, *id};
    return std::nullopt;
}

void Jobs::worker() {
    for (;;) {
        std::optional<Job> job;
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
            if (job) running_[{job->kind, job->id}] = flag;
        }
        if (!job) {
            std::unique_lock lk(mu_);
            cv_.wait_for(lk, std::chrono::seconds(2), [this, seq] { return stopping_ || wake_seq_ != seq; });
            continue;
        }
        if (job->kind == Kind::Run)
            execute(job->id, *flag);
        else
            optimize(job->id, *flag);
        {
            std::lock_guard lk(mu_);
            running_.erase({job->kind, job->id});
        }
        idle_cv_.notify_all();
    }
}

void Jobs::finish(Kind kind, std::int64_t id, db::JobState state, const std::string& error) {
    store_.session()->jobs().finish(queue_of(kind), id, state, error.empty() ? std::nullopt : std::optional<std::string>(error),
                                    db::now_iso());
}

void Jobs::execute(std::int64_t id, const std::atomic<bool>& cancel) {
    const auto t_start = std::chrono::steady_clock::now();
    auto elapsed_s = [&] {
        return std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
    };
    try {
        json inputs;
        fs::path dir;
        std::optional<std::int64_t> base_run;
        {
            const auto run = store_.session()->runs().get(id);
            if (!run) return;   // deleted meanwhile
            dir = data_dir_ / run->upload_dir;
            inputs = json::parse(run->inputs_json);
            base_run = run->base_run;
        }
        app::RunInput in = run_input(inputs, dir, opt_.use_opencl);
        const force_model::StockPtr base = load_base_stock(store_, base_run);
        in.base_stock = base.get();

        app::Control control;
        control.cancel = &cancel;
        auto last_write = std::chrono::steady_clock::now() - std::chrono::seconds(1);
        control.progress = [&](app::Phase, double f) {
            // At most a few writes per second: progress is for people polling, not an audit trail.
            auto now = std::chrono::steady_clock::now();
            if (now - last_write < std::chrono::milliseconds(250)) return;
            last_write = now;
            store_.session()->jobs().set_progress(db::kRunQueue, id, f);
        };
        const app::RunResult r = app::predict_run(in, control);
        const std::string stock_bytes = force_model::save_stock_bytes(*r.prediction.final_stock);

        if (cancel) throw force_model::Cancelled();   // nothing stored for a run cancelled at the finish
        int alerts = 0;
        {
            auto s = store_.session();
            std::optional<ProgramResult> program_result;
            if (r.program)
                program_result.emplace(ProgramResult{*r.program, *r.commanded, inputs["nc_program"].value("filename", "")});
            alerts = store_result(*s, id, r.motion, r.prediction, stock_bytes, program_result ? &*program_result : nullptr,
                                  opt_.limit_alerts);
        }
        metrics_.job_finished("done", elapsed_s());
        if (alerts > 0) {
            metrics_.alerts_raised(alerts);
            on_alerts_();
        }
        spdlog::info("run {} done in {:.2f} s ({} samples, {} alerts{})", id, elapsed_s(), r.prediction.samples.size(), alerts,
                     r.program ? ", with the commanded prediction" : "");
    } catch (const force_model::Cancelled&) {
        const bool requeue = requeue_on_cancel_.load();
        finish(Kind::Run, id, requeue ? db::JobState::Queued : db::JobState::Cancelled, "");
        metrics_.job_finished(requeue ? "requeued" : "cancelled", elapsed_s());
        spdlog::info("run {} {}", id, requeue ? "interrupted by shutdown, re-queued" : "cancelled");
    } catch (const std::exception& e) {
        finish(Kind::Run, id, db::JobState::Failed, e.what());
        metrics_.job_finished("failed", elapsed_s());
        spdlog::warn("run {} failed: {}", id, e.what());
    }
}

void Jobs::optimize(std::int64_t id, const std::atomic<bool>& cancel) {
    const auto t_start = std::chrono::steady_clock::now();
    auto last_write = t_start - std::chrono::seconds(1);
    auto progress = [&](double f) {
        auto now = std::chrono::steady_clock::now();
        if (now - last_write < std::chrono::milliseconds(250)) return;
        last_write = now;
        store_.session()->jobs().set_progress(db::kOptimizationQueue, id, f);
    };
    auto elapsed_s = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count(); };
    try {
        if (!run_optimization(store_, data_dir_, opt_.use_opencl, id, cancel, progress)) {
            spdlog::info("optimization {} was deleted while computing; nothing stored", id);
            return;
        }
        metrics_.optimization_finished("done", elapsed_s());
        spdlog::info("optimization {} done in {:.2f} s", id, elapsed_s());
    } catch (const force_model::Cancelled&) {
        const bool requeue = requeue_on_cancel_.load();
        finish(Kind::Optimization, id, requeue ? db::JobState::Queued : db::JobState::Cancelled, "");
        metrics_.optimization_finished(requeue ? "requeued" : "cancelled", elapsed_s());
    } catch (const std::exception& e) {
        finish(Kind::Optimization, id, db::JobState::Failed, e.what());
        metrics_.optimization_finished("failed", elapsed_s());
        spdlog::warn("optimization {} failed: {}", id, e.what());
    }
}

}  // namespace cutload::server
