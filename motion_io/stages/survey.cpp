#include "stages/survey.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace cutload::motion_io::detail {

void Survey::ChannelStats::add(double t_s) {
    ++samples;
    if (have_last && t_s >= last_t) intervals.add(t_s - last_t);
    have_last = true;
    last_t = t_s;
}

Survey::Survey(Diagnostics& diag, bool event_driven) : Stage("survey"), diag_(diag), event_driven_(event_driven) {}

void Survey::begin_session() {
    session_ = SessionSummary{};
    last_pos_.reset();
    feed_now_.reset();
    feed_since_pos_mm_ = 0;
    usual_dt_ = 0;
    for (ChannelStats* c : {&pos_stats_, &feed_stats_, &spindle_stats_, &block_stats_, &tool_stats_}) c->have_last = false;
    emit_begin_session();
}

void Survey::record(const Record& r) {
    switch (r.ch) {
        case Chan::Pos:
            on_position(r);
            emit(Flow::Positions, r);
            break;
        case Chan::Feed:
            on_feed(r);
            break;
        case Chan::Spindle:
            spindle_stats_.add(r.t_s);
            emit(Flow::Spindle, r);
            break;
        case Chan::Block:
            block_stats_.add(r.t_s);
            emit(Flow::Blocks, r);
            break;
        case Chan::Tool:
            tool_stats_.add(r.t_s);
            emit(Flow::Blocks, r);
            break;
        default:
            break;
    }
}

void Survey::advance_feed(double t_s) {
    if (feed_now_ && t_s > feed_t_) feed_since_pos_mm_ += *feed_now_ / 60.0 * (t_s - feed_t_);
    if (!feed_now_ || t_s > feed_t_) feed_t_ = t_s;
}

void Survey::on_feed(const Record& r) {
    feed_stats_.add(r.t_s);
    advance_feed(r.t_s);
    feed_now_ = r.v[0];
    feed_t_ = r.t_s;
}

void Survey::on_position(const Record& r) {
    pos_stats_.add(r.t_s);
    advance_feed(r.t_s);
    const double feed_mm = feed_since_pos_mm_;
    feed_since_pos_mm_ = 0;
    if (session_.position_reads++ == 0) {
        session_.first_t_s = r.t_s;
        session_.first_line = r.line;
    }
    session_.last_t_s = r.t_s;
    if (last_pos_) {
        const double dt = r.t_s - last_pos_->t_s;
        const double d = std::sqrt((r.v[0] - last_pos_->v[0]) * (r.v[0] - last_pos_->v[0]) +
                                   (r.v[1] - last_pos_->v[1]) * (r.v[1] - last_pos_->v[1]) +
                                   (r.v[2] - last_pos_->v[2]) * (r.v[2] - last_pos_->v[2]));
        double turn2 = 0;
        for (int k = 0; k < 3; ++k) turn2 += (r.rot_deg[k] - last_pos_->rot_deg[k]) * (r.rot_deg[k] - last_pos_->rot_deg[k]);
        if (std::sqrt(turn2) * kRotaryMmPerDeg <= kRotaryStandingShare * d) {
            path_length_mm_ += d;
            feed_integral_mm_ += feed_mm;
        }
        if (dt > 0) {
            // What plain differencing of consecutive readings would call the feed.
            const double f = d / dt * 60.0;
            raw_min_ = have_raw_feed_ ? std::min(raw_min_, f) : f;
            raw_max_ = have_raw_feed_ ? std::max(raw_max_, f) : f;
            have_raw_feed_ = true;
        }
        if (!event_driven_ && dt > 0) follow_interval(dt, r.line);
    }
    last_pos_ = r;
}

// The usual interval follows the log slowly; a gap does not enter it.
void Survey::follow_interval(double dt_s, std::size_t line) {
    if (usual_dt_ > 0 && dt_s > 10 * usual_dt_ && dt_s > 0.05)
        diag_.warn("gap", line, fmt::format("no position reading for {:.3f} s (usual interval {:.4f} s); "
                                            "interpolated across", dt_s, usual_dt_));
    else
        usual_dt_ = usual_dt_ > 0 ? 0.95 * usual_dt_ + 0.05 * dt_s : dt_s;
}

void Survey::end_session(SessionSummary& s) {
    if (session_.position_reads >= 2 && session_.last_t_s == session_.first_t_s)
        diag_.fail(session_.first_line, fmt::format("time never advances: {} position samples all at t = {} s",
                                                    session_.position_reads, session_.first_t_s));
    s.position_reads = session_.position_reads;
    s.first_line = session_.first_line;
    s.first_t_s = session_.first_t_s;
    s.last_t_s = session_.last_t_s;
    emit_end_session(s);
}

void Survey::report(IngestReport& report) const {
    auto channel = [](const ChannelStats& c) {
        ChannelReport r;
        r.samples = c.samples;
        r.interval = c.intervals.stats();
        return r;
    };
    report.channels["pos"] = channel(pos_stats_);
    if (feed_stats_.samples) report.channels["feed"] = channel(feed_stats_);
    if (spindle_stats_.samples) report.channels["spindle"] = channel(spindle_stats_);
    if (block_stats_.samples) report.channels["block"] = channel(block_stats_);
    if (tool_stats_.samples) report.channels["tool"] = channel(tool_stats_);
    report.feed_raw_min_mm_min = raw_min_;
    report.feed_raw_max_mm_min = raw_max_;
}

double Survey::feed_to_path_ratio() const {
    if (feed_stats_.samples < 10 || path_length_mm_ < 1.0 || feed_integral_mm_ <= 0) return 0;
    return feed_integral_mm_ / path_length_mm_;
}

}  // namespace cutload::motion_io::detail
