#include "metrics.hpp"

#include <fmt/format.h>

namespace cutload::server {

void Metrics::request(const std::string& method, const std::string& route, int status, double seconds) {
    std::lock_guard lk(mu_);
    ++requests_[{method, route, status}];
    auto& h = latency_[route];
    for (std::size_t i = 0; i < kBuckets.size(); ++i)
        if (seconds <= kBuckets[i]) ++h.le[i];
    ++h.count;
    h.sum += seconds;
}

const char* outcome_name(JobOutcome o) {
    switch (o) {
        case JobOutcome::Done: return "done";
        case JobOutcome::Failed: return "failed";
        case JobOutcome::Cancelled: return "cancelled";
        case JobOutcome::Requeued: return "requeued";
    }
    return "?";
}

void Metrics::job_finished(const JobMetricNames& kind, JobOutcome outcome, double compute_s) {
    std::lock_guard lk(mu_);
    ++finished_[kind.finished][outcome];
    compute_s_ += compute_s;
}

void Metrics::webhook_attempt(bool ok) {
    std::lock_guard lk(mu_);
    ++(ok ? webhook_ok_ : webhook_fail_);
}

void Metrics::alerts_raised(int n) {
    std::lock_guard lk(mu_);
    alerts_ += n;
}

std::string Metrics::render(const std::vector<Queue>& queues, long running, long pending_deliveries) const {
    std::lock_guard lk(mu_);
    std::string out;
    auto line = [&out]<class... A>(fmt::format_string<A...> f, A&&... a) {
        fmt::format_to(std::back_inserter(out), f, std::forward<A>(a)...);
    };
    line("# HELP cutload_http_requests_total HTTP requests by method, route template and status.\n");
    line("# TYPE cutload_http_requests_total counter\n");
    for (const auto& [k, n] : requests_)
        line("cutload_http_requests_total{{method=\"{}\",route=\"{}\",status=\"{}\"}} {}\n", std::get<0>(k),
             std::get<1>(k), std::get<2>(k), n);
    line("# HELP cutload_http_request_duration_seconds Time spent in the handler.\n");
    line("# TYPE cutload_http_request_duration_seconds histogram\n");
    for (const auto& [route, h] : latency_) {
        for (std::size_t i = 0; i < kBuckets.size(); ++i)
            line("cutload_http_request_duration_seconds_bucket{{route=\"{}\",le=\"{}\"}} {}\n", route, kBuckets[i],
                 h.le[i]);
        line("cutload_http_request_duration_seconds_bucket{{route=\"{}\",le=\"+Inf\"}} {}\n", route, h.count);
        line("cutload_http_request_duration_seconds_sum{{route=\"{}\"}} {}\n", route, h.sum);
        line("cutload_http_request_duration_seconds_count{{route=\"{}\"}} {}\n", route, h.count);
    }
    for (const Queue& q : queues) {
        const JobMetricNames& k = *q.kind;
        line("# HELP {} {}\n# TYPE {} counter\n", k.finished, k.finished_help, k.finished);
        const auto counts = finished_.find(k.finished);
        for (const JobOutcome outcome : kJobOutcomes) {
            long n = 0;
            if (counts != finished_.end())
                if (auto it = counts->second.find(outcome); it != counts->second.end()) n = it->second;
            line("{}{{state=\"{}\"}} {}\n", k.finished, outcome_name(outcome), n);
        }
        line("# HELP {} {}\n# TYPE {} gauge\n{} {}\n", k.queued, k.queued_help, k.queued, k.queued, q.queued);
    }
    line("# HELP cutload_job_compute_seconds_total Wall seconds spent computing jobs of every kind.\n");
    line("# TYPE cutload_job_compute_seconds_total counter\ncutload_job_compute_seconds_total {}\n", compute_s_);
    line("# HELP cutload_jobs_running Jobs being computed, of every kind.\n");
    line("# TYPE cutload_jobs_running gauge\ncutload_jobs_running {}\n", running);
    line("# HELP cutload_alerts_total Alerts raised by thresholds.\n");
    line("# TYPE cutload_alerts_total counter\ncutload_alerts_total {}\n", alerts_);
    line("# HELP cutload_webhook_attempts_total Webhook POST attempts by result.\n");
    line("# TYPE cutload_webhook_attempts_total counter\n");
    line("cutload_webhook_attempts_total{{result=\"ok\"}} {}\n", webhook_ok_);
    line("cutload_webhook_attempts_total{{result=\"error\"}} {}\n", webhook_fail_);
    line("# HELP cutload_webhook_deliveries_pending Deliveries waiting for their next attempt.\n");
    line("# TYPE cutload_webhook_deliveries_pending gauge\ncutload_webhook_deliveries_pending {}\n",
         pending_deliveries);
    return out;
}

}  // namespace cutload::server
