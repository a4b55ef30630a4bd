#include "stages/chain.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <stdexcept>

namespace cutload::motion_io::detail {
namespace {

constexpr Flow kAllFlows[kFlowKinds] = {Flow::Readings, Flow::Checked, Flow::Sessions, Flow::Positions, Flow::Feed,
                                        Flow::Spindle,  Flow::Blocks,  Flow::Ticks,    Flow::Knots,     Flow::Grid};

}  // namespace

const char* flow_name(Flow k) {
    static constexpr const char* names[kFlowKinds] = {"readings",       "checked readings", "sessions",
                                                      "positions",      "feed readings",    "spindle readings",
                                                      "block readings", "ticks",            "knots",
                                                      "grid samples"};
    return names[flow_index(k)];
}

void Stage::emit_finish() {
    for (Flow k : {Flow::Checked, Flow::Readings})
        if (Stage* next = routes_[flow_index(k)]) {
            next->finish();
            return;
        }
}

// The end of every chain: hands the grid to the sink and keeps what the report needs from each
// session's summary.
class StageChain::Terminal final : public Stage {
public:
    explicit Terminal(GridSink& sink) : Stage("sink"), sink_(sink) {}
    Flows accepts() const override { return Flow::Sessions | Flow::Grid; }
    Flows emits() const override { return 0; }
    void begin_session() override {
        ++sessions_;
        sink_.begin_session();
    }
    void grid(std::span<GridSample> batch) override {
        for (const GridSample& s : batch) sink_.sample(s);
    }
    void end_session(SessionSummary& s) override {
        duration_s_ += s.last_t_s - s.first_t_s;
        // The report gives one period: that of the session with the most position readings.
        if (s.position_reads > best_period_reads_) {
            best_period_reads_ = s.position_reads;
            best_period_s_ = s.period_s;
        }
    }
    void report(IngestReport& r) const override {
        r.sessions = sessions_;
        r.duration_s = duration_s_;
        r.channels["pos"].update_period_s = best_period_s_;
    }

private:
    GridSink& sink_;
    std::size_t sessions_ = 0;
    double duration_s_ = 0;
    double best_period_s_ = 0;
    std::size_t best_period_reads_ = 0;
};

StageChain::StageChain(GridSink& sink) : terminal_(std::make_unique<Terminal>(sink)) {}
StageChain::~StageChain() = default;

void StageChain::append(std::unique_ptr<Stage> stage) {
    stages_.push_back(std::move(stage));
    entry_ = nullptr;
}

std::size_t StageChain::index_of(std::string_view name) const {
    for (std::size_t i = 0; i < stages_.size(); ++i)
        if (stages_[i]->name() == name) return i;
    throw std::logic_error(fmt::format("ingest chain: no stage named '{}'", name));
}

void StageChain::insert_before(std::string_view name, std::unique_ptr<Stage> stage) {
    stages_.insert(stages_.begin() + static_cast<long>(index_of(name)), std::move(stage));
    bind();
}

void StageChain::insert_after(std::string_view name, std::unique_ptr<Stage> stage) {
    stages_.insert(stages_.begin() + static_cast<long>(index_of(name)) + 1, std::move(stage));
    bind();
}

std::unique_ptr<Stage> StageChain::remove(std::string_view name) {
    const std::size_t i = index_of(name);
    std::unique_ptr<Stage> out = std::move(stages_[i]);
    stages_.erase(stages_.begin() + static_cast<long>(i));
    bind();
    return out;
}

Stage* StageChain::find(std::string_view name) const {
    for (const auto& s : stages_)
        if (s->name() == name) return s.get();
    return nullptr;
}

std::vector<std::string> StageChain::names() const {
    std::vector<std::string> out;
    for (const auto& s : stages_) out.push_back(s->name());
    return out;
}

// Walks the chain with the kinds in flight: each stage takes the kinds it accepts from their
// producers and puts the kinds it emits in flight; whatever is still in flight at the sink has
// no consumer.
void StageChain::bind() {
    entry_ = nullptr;
    std::array<Stage*, kFlowKinds> producer{};   // who emitted each kind in flight (nullptr: the reader)
    Flows in_flight = static_cast<Flows>(Flow::Readings);
    std::vector<Stage*> order;
    for (const auto& s : stages_) order.push_back(s.get());
    order.push_back(terminal_.get());
    for (Stage* s : order) {
        s->routes_.fill(nullptr);
        // The sink takes sessions and grid samples where they flow (a chain of a few stages
        // under test may end before the grid).
        const Flows accepted = s == terminal_.get() ? static_cast<Flows>(s->accepts() & in_flight) : s->accepts();
        for (Flow k : kAllFlows) {
            if (!has(accepted, k)) continue;
            if (!has(in_flight, k))
                throw std::logic_error(fmt::format("ingest chain: stage '{}' accepts {}, which no stage before it emits",
                                                   s->name(), flow_name(k)));
            if (Stage* p = producer[flow_index(k)])
                p->routes_[flow_index(k)] = s;
            else
                entry_ = s;
            in_flight &= static_cast<Flows>(~static_cast<Flows>(k));
        }
        for (Flow k : kAllFlows) {
            if (!has(s->emits(), k)) continue;
            if (has(in_flight, k))
                throw std::logic_error(fmt::format("ingest chain: stage '{}' emits {}, which already flow past it",
                                                   s->name(), flow_name(k)));
            in_flight |= static_cast<Flows>(k);
            producer[flow_index(k)] = s;
        }
    }
    for (Flow k : kAllFlows)
        if (has(in_flight, k))
            throw std::logic_error(fmt::format("ingest chain: {} emitted by '{}' reach no stage", flow_name(k),
                                               producer[flow_index(k)] ? producer[flow_index(k)]->name() : "the reader"));
}

void StageChain::fill_report(IngestReport& report) const {
    for (const auto& s : stages_) s->report(report);
    terminal_->report(report);
}

}  // namespace cutload::motion_io::detail
