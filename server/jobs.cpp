#include "jobs.hpp"

#include "program.hpp"
#include "results.hpp"
#include "db/jobs.hpp"
#include "db/runs.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <fstream>
#include <sstream>

namespace cutload::server {
namespace fs = std::filesystem;

namespace {

motion_io::ReadOptions read_options(const json& log, const fs::path& dir) {
    motion_io::ReadOptions o;
    const std::string fmt_name = log.value("format", "auto");
    o.format = fmt_name == "csv" ? motion_io::Format::Csv
             : fmt_name == "shdr" ? motion_io::Format::Shdr
                                  : motion_io::Format::Auto;
    if (log.contains("mapping") && log["mapping"].is_string()) o.map_file = (dir / log["mapping"].get<std::string>()).string();
    if (log.contains("units") && log["units"].is_string()) o.length_unit = log["units"].get<std::string>();
    if (log.contains("feed_units") && log["feed_units"].is_string()) o.feed_unit = log["feed_units"].get<std::string>();
    return o;
}

std::string read_file(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    std::ostringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

const db::JobQueue& queue_of(Jobs::Kind kind) { return kind == Jobs::Kind::Run ? db::kRunQueue : db::kOptimizationQueue; }

}  // namespace

motion_io::MotionModel ingest_run_log(const json& inputs, const fs::path& upload_dir) {
    const json& log = inputs.at("log");
    return motion_io::ingest((upload_dir / log.at("stored_as").get<std::string>()).string(), read_options(log, upload_dir));
}

force_model::StockPtr load_base_stock(db::Store& store, std::optional<std::int64_t> base_run, const fs::path& scratch_dir) {
    if (!base_run) return nullptr;
    const auto bytes = store.session()->runs().final_stock(*base_run);
    if (!bytes) throw std::runtime_error(fmt::format("base_run {}: its final stock is gone (run deleted?)", *base_run));
    const fs::path tmp = scratch_dir / fmt::format("base-{}.stock", std::hash<std::thread::id>{}(std::this_thread::get_id()));
    std::ofstream(tmp, std::ios::binary).write(bytes->data(), static_cast<std::streamsize>(bytes->size()));
    auto stock = force_model::load_stock(tmp.string());
    fs::remove(tmp);
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
        auto motion = ingest_run_log(inputs, dir);
        // Ingest itself cannot be interrupted; honour a cancel that arrived meanwhile.
        if (cancel) throw force_model::Cancelled();
        auto spec = force_model::parse_run_spec(inputs.at("spec"));
        // Before predicting: a log without block numbers takes the program's blocks by mapping.
        std::optional<force_model::ProgramRun> program;
        if (inputs.contains("nc_program")) program = load_program_run(inputs, dir, spec, motion);
        const force_model::StockPtr base = load_base_stock(store_, base_run, dir);

        force_model::PredictOptions po;
        po.device = opt_.use_opencl ? force_model::Device::OpenCL : force_model::Device::Cpu;
        po.base_stock = base.get();
        po.cancel = &cancel;
        // With a program, the commanded prediction follows the actual one; share the bar by duration.
        double share = 1, offset = 0;
        if (program) {
            const auto commanded_s = motion_io::commanded_durations_s(program->program, program->commanded);
            double total_s = 0;
            for (double d : commanded_s) total_s += d;
            const double actual_s = motion.t_s.back() - motion.t_s.front();
            share = actual_s / std::max(1e-9, actual_s + total_s);
        }
        auto last_write = std::chrono::steady_clock::now() - std::chrono::seconds(1);
        po.progress = [&](double f) {
            // At most a few writes per second: progress is for people polling, not an audit trail.
            auto now = std::chrono::steady_clock::now();
            if (now - last_write < std::chrono::milliseconds(250)) return;
            last_write = now;
            store_.session()->jobs().set_progress(db::kRunQueue, id, offset + share * f);
        };
        auto prediction = force_model::predict(motion, spec, po);
        std::optional<force_model::ProgramPrediction> commanded;
        if (program) {
            offset = share;
            share = 1 - share;
            commanded = force_model::predict_program(*program, motion, prediction, spec, po);
        }

        fs::path stock_file = dir / "final.stock";
        force_model::save_stock(*prediction.final_stock, stock_file.string());
        std::string stock_bytes = read_file(stock_file);
        fs::remove(stock_file);

        if (cancel) throw force_model::Cancelled();   // nothing stored for a run cancelled at the finish
        int alerts = 0;
        {
            auto s = store_.session();
            std::optional<ProgramResult> program_result;
            if (program) program_result.emplace(ProgramResult{*program, *commanded, inputs["nc_program"].value("filename", "")});
            alerts = store_result(*s, id, motion, prediction, stock_bytes, program_result ? &*program_result : nullptr);
        }
        metrics_.job_finished("done", elapsed_s());
        if (alerts > 0) {
            metrics_.alerts_raised(alerts);
            on_alerts_();
        }
        spdlog::info("run {} done in {:.2f} s ({} samples, {} alerts{})", id, elapsed_s(), prediction.samples.size(), alerts,
                     program ? ", with the commanded prediction" : "");
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
