// The public push interface of the ingest stages (motion_io/ingest_chain.hpp).
#include "motion_io/ingest_chain.hpp"

#include "pipeline.hpp"
#include "stages/standard.hpp"

#include <fmt/format.h>

#include <stdexcept>

namespace cutload::motion_io {
namespace {

class ConsumerSink final : public detail::GridSink {
public:
    explicit ConsumerSink(MotionConsumer& out) : out_(out) {}
    void begin_session() override { out_.begin_session(); }
    void sample(const detail::GridSample& g) override {
        MotionState s;
        s.t_s = g.t_s;
        for (int k = 0; k < 3; ++k) s.pos_mm[k] = g.p_mm[k], s.vel_mm_s[k] = g.v_mm_s[k];
        for (int k = 0; k < 3; ++k) s.rot_deg[k] = g.rot_deg[k], s.rot_vel_deg_s[k] = g.rot_vel_deg_s[k];
        s.spindle_rpm = g.spindle_rpm;
        s.spindle_angle_deg = g.spindle_angle_deg;
        s.block = g.block;
        s.tool = g.tool;
        out_.sample(s);
    }

private:
    MotionConsumer& out_;
};

detail::Chan chan_of(LogReading::Channel c) {
    switch (c) {
        case LogReading::Channel::Feed: return detail::Chan::Feed;
        case LogReading::Channel::Spindle: return detail::Chan::Spindle;
        case LogReading::Channel::Block: return detail::Chan::Block;
        case LogReading::Channel::Position: break;
    }
    return detail::Chan::Pos;
}

}  // namespace

struct IngestChain::Impl {
    Impl(const ChainOptions& opt, MotionConsumer& out) : diag(opt.source), sink(out) {
        if (!(opt.step_ms >= 0.01 && opt.step_ms <= 1000))
            throw IngestError(fmt::format("step must be from 0.01 to 1000 ms, got {}", opt.step_ms));
        detail::ChainSettings s;
        s.step_s = opt.step_ms * 1e-3;
        s.event_driven = opt.event_driven;
        s.clock.batch_readings = std::max<std::size_t>(opt.clock_batch_readings, 1);
        if (!(opt.reorder_horizon_s >= 0 && opt.reorder_horizon_s <= 60))
            throw IngestError(fmt::format("reorder horizon must be from 0 to 60 s, got {}", opt.reorder_horizon_s));
        s.limits.reorder_horizon_s = opt.reorder_horizon_s;
        chain = detail::make_ingest_chain(diag, sink, s);
    }
    detail::Diagnostics diag;
    detail::BlockTable blocks;
    ConsumerSink sink;
    std::unique_ptr<detail::StageChain> chain;
};

IngestChain::IngestChain(const ChainOptions& opt, MotionConsumer& out) : impl_(std::make_unique<Impl>(opt, out)) {}
IngestChain::~IngestChain() = default;

void IngestChain::push(const LogReading& r) {
    detail::Record rec;
    rec.t_s = r.t_s;
    rec.line = r.line;
    rec.ch = chan_of(r.channel);
    for (int k = 0; k < 3; ++k) rec.v[k] = r.value[k];
    if (rec.ch == detail::Chan::Block) rec.block = impl_->blocks.intern(r.block);
    impl_->chain->push(rec);
}

void IngestChain::push_axis(int axis, double t_s, double value_mm, std::size_t line) {
    if (axis < 0 || axis > 2) throw std::invalid_argument(fmt::format("axis {} is not 0 (x), 1 (y) or 2 (z)", axis));
    detail::Record rec;
    rec.t_s = t_s;
    rec.line = line;
    rec.ch = static_cast<detail::Chan>(static_cast<int>(detail::Chan::AxisX) + axis);
    rec.v[0] = value_mm;
    impl_->chain->push(rec);
}

void IngestChain::flush() { impl_->chain->finish(); }

IngestReport IngestChain::report() const {
    IngestReport r;
    impl_->chain->fill_report(r);
    r.file = impl_->diag.file();
    r.format = "live";
    r.blocks = impl_->blocks.names().size();
    r.warnings = impl_->diag.warnings();
    return r;
}

const std::vector<std::string>& IngestChain::block_names() const { return impl_->blocks.names(); }

std::vector<std::string> IngestChain::stage_names() const { return impl_->chain->names(); }

}  // namespace cutload::motion_io
