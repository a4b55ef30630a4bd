// Internal to server: Prometheus counters, gauges and a latency histogram, in the text exposition
// format. Routes are labelled by their template (/api/v1/runs/{id}), never the raw path, so the
// label set stays bounded.
#pragma once

#include <array>
#include <atomic>
#include <map>
#include <mutex>
#include <string>
#include <tuple>
#include <vector>

namespace cutload::server {

// How a claimed job ended, as the metrics count it (requeued: interrupted by a shutdown).
enum class JobOutcome { Done, Failed, Cancelled, Requeued };
inline constexpr JobOutcome kJobOutcomes[] = {JobOutcome::Done, JobOutcome::Failed, JobOutcome::Cancelled,
                                              JobOutcome::Requeued};
const char* outcome_name(JobOutcome o);

// What one kind of job is called in the metrics: a counter of finished jobs by final state and a
// gauge of queued ones, each with its help text.
struct JobMetricNames {
    std::string finished, finished_help;
    std::string queued, queued_help;
};

class Metrics {
public:
    void request(const std::string& method, const std::string& route, int status, double seconds);
    void job_finished(const JobMetricNames& kind, JobOutcome outcome, double compute_s);
    void webhook_attempt(bool ok);
    void alerts_raised(int n);

    // Gauges are read at scrape time by the caller and passed in: the queued jobs of each kind
    // (every kind's counters are written, at 0 before its first job finishes).
    struct Queue {
        const JobMetricNames* kind;
        long queued;
    };
    std::string render(const std::vector<Queue>& queues, long running, long pending_deliveries) const;

private:
    static constexpr std::array<double, 12> kBuckets{0.001, 0.0025, 0.005, 0.01, 0.025, 0.05,
                                                     0.1,   0.25,   0.5,   1,    2.5,   10};
    struct Hist {
        std::array<long, kBuckets.size()> le{};
        long count = 0;
        double sum = 0;
    };
    mutable std::mutex mu_;
    std::map<std::tuple<std::string, std::string, int>, long> requests_;
    std::map<std::string, Hist> latency_;
    std::map<std::string, std::map<JobOutcome, long>> finished_;   // counter name -> outcome -> count
    double compute_s_ = 0;
    long webhook_ok_ = 0, webhook_fail_ = 0, alerts_ = 0;
};

}  // namespace cutload::server
