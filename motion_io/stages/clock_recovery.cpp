#include "stages/clock_recovery.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace cutload::motion_io::detail {
namespace {

constexpr std::size_t kPhaseChunk = 64;            // readings per phase estimate (follows clock drift)
constexpr std::size_t kCalibrationMinReads = 1024;  // readings the period is estimated from, at any batch size
constexpr std::size_t kCalibrationMaxWait = 16384; // readings held while waiting for motion
constexpr std::size_t kCalibrationReads = 2048;
constexpr std::size_t kMinMovingPairs = 40;
constexpr int kCalibrationAttempts = 3;
// Period scans per log. A scan costs about as much as timing 10^5 readings, and a log of many
// short sessions would pay one per session (1000 sessions of 30 rows: 3 minutes for 1 MB); one
// CNC keeps its update period, so later sessions take the period an earlier one found.
constexpr std::size_t kMaxPeriodScans = 8;

std::size_t moving_pairs(const std::vector<PosRead>& r) {
    std::size_t c = 0;
    for (std::size_t k = 1; k < r.size(); ++k) c += moved(r[k - 1], r[k]);
    return c;
}

PosRead as_read(const Tick& t) {
    PosRead r;
    std::copy(t.p_mm, t.p_mm + 3, r.p_mm);
    std::copy(t.rot_deg, t.rot_deg + 3, r.rot_deg);
    return r;
}

}  // namespace

ClockRecovery::ClockRecovery(Diagnostics& diag, bool event_driven, ClockLimits limits)
    : Stage("clock"), diag_(diag), event_driven_(event_driven), limits_(limits) {}

void ClockRecovery::begin_session() {
    pending_.clear();
    pending_stamp_s_.clear();
    period_s_ = phase_s_ = ref_phase_s_ = 0;
    have_ref_phase_ = false;
    calibration_attempts_ = 0;
    last_committed_.reset();
    last_tick_.reset();
    have_first_line_ = false;
    emit_begin_session();
}

void ClockRecovery::record(const Record& r) {
    if (!have_first_line_) first_line_ = r.line, have_first_line_ = true, origin_s_ = r.t_s;
    PosRead read;
    read.t_s = r.t_s - origin_s_;
    std::copy(r.v, r.v + 3, read.p_mm);
    std::copy(r.rot_deg, r.rot_deg + 3, read.rot_deg);
    pending_.push_back(read);
    pending_stamp_s_.push_back(r.t_s);
    // Without a grid a reading's time is its own stamp, so batching would only delay it (a live
    // source's lag); the one-reading look-ahead stays.
    const std::size_t batch = event_driven_ ? 2 : limits_.batch_readings;
    if (pending_.size() >= batch) process_batch(false);
}

void ClockRecovery::end_session(SessionSummary& s) {
    process_batch(true);
    s.period_s = period_s_;
    emit_end_session(s);
}

// False while the calibration waits for more motion (the batch stays pending).
bool ClockRecovery::calibrate(bool final) {
    if (!final && pending_.size() < kCalibrationMinReads) return false;
    const std::size_t pairs = moving_pairs(pending_);
    if (pairs < kMinMovingPairs && !final && pending_.size() < kCalibrationMaxWait) return false;
    // A session that ends before the streaming wait is over still gets its grid from the
    // little it has.
    if (pairs >= kMinMovingPairs || (final && pairs >= kMinPeriodPairs)) {
        ++calibration_attempts_;
        // Calibrate on the moving stretch, starting one reading before its first move.
        std::size_t first = 1;
        while (first < pending_.size() && !moved(pending_[first - 1], pending_[first])) ++first;
        const std::size_t begin = first - 1, end = std::min(pending_.size(), begin + kCalibrationReads);
        const std::vector<PosRead> stretch(pending_.begin() + static_cast<long>(begin),
                                           pending_.begin() + static_cast<long>(end));
        // A short stretch (the costliest scan, and the least precise) or a spent scan budget
        // first tries the period an earlier session of this log found.
        const bool scan_allowed = scans_ < kMaxPeriodScans;
        if (known_period_s_ > 0 && (stretch.size() <= kShortStretchReads || !scan_allowed) &&
            period_fits(stretch, known_period_s_)) {
            period_s_ = known_period_s_;
        } else if (scan_allowed) {
            ++scans_;
            const UpdatePeriod found = estimate_update_period(stretch, limits_.scan_threads);
            period_s_ = found.period_s;
            if (period_s_ > 0) known_period_s_ = period_s_;
            if (period_s_ > 0 && found.nominal) warn_short_stretch(found, end - begin);
        } else {
            diag_.warn("period_not_estimated", first_line_,
                       fmt::format("CNC update period not searched for this session: {} sessions of the log were "
                                   "searched already{}; its readings keep their time stamps",
                                   kMaxPeriodScans, known_period_s_ > 0 ? " and the period found does not fit it" : ""));
            calibration_attempts_ = kCalibrationAttempts;   // not again for this session
        }
    }
    return true;
}

void ClockRecovery::process_batch(bool final) {
    if (pending_.empty()) return;
    if (period_s_ == 0 && calibration_attempts_ < kCalibrationAttempts && !event_driven_ && !calibrate(final)) return;
    // The last reading stays for the next batch: timing a reading looks at its successor.
    const std::size_t commit = final ? pending_.size() : pending_.size() - 1;
    for (std::size_t s = 0; s < commit; s += kPhaseChunk) time_chunk(s, std::min(commit, s + kPhaseChunk));
    pending_.erase(pending_.begin(), pending_.begin() + static_cast<long>(commit));
    pending_stamp_s_.erase(pending_stamp_s_.begin(), pending_stamp_s_.begin() + static_cast<long>(commit));
}

// The chunk's phase picks each reading's tick; its time is put on the reference grid, which
// follows the chunk phases slowly and is moved gradually across the chunk, so neither phase
// noise nor clock drift jolts the velocity.
void ClockRecovery::time_chunk(std::size_t s, std::size_t e) {
    double ref_before = ref_phase_s_, ref_step = 0;
    if (period_s_ > 0) {
        std::vector<PosRead> chunk;
        chunk.reserve(kPhaseChunk + 1);
        if (last_committed_) chunk.push_back(*last_committed_);
        chunk.insert(chunk.end(), pending_.begin() + static_cast<long>(s), pending_.begin() + static_cast<long>(e));
        phase_s_ = best_phase(chunk.data(), chunk.size(), period_s_, phase_s_);
        if (!have_ref_phase_) ref_before = phase_s_;
        follow_phase();
        ref_step = wrap_half_period(ref_phase_s_ - ref_before);
    }
    const double shift = period_s_ > 0 ? wrap_half_period(ref_before - phase_s_) : 0.0;
    for (std::size_t k = s; k < e; ++k) {
        const double ramp = ref_step * static_cast<double>(k - s + 1) / static_cast<double>(e - s);
        // Without a grid a reading keeps its own stamp, exactly (not origin + (stamp - origin)).
        add_tick(tick_of(k) + shift + ramp, period_s_ > 0 ? std::nullopt : std::optional(pending_stamp_s_[k]),
                 pending_[k]);
        last_committed_ = pending_[k];
    }
}

// Too few readings to measure the period by its phase drift: say what the time stamps allowed
// and what was taken, so a user can judge a feed that rests on it.
void ClockRecovery::warn_short_stretch(const UpdatePeriod& found, std::size_t reads) {
    diag_.warn("period_short_log", first_line_,
               fmt::format("CNC update period from {} position readings only (too few to measure its drift): the "
                           "time stamps allow {:.3f} to {:.3f} ms; the nominal {:.3f} ms inside it taken",
                           reads, found.min_s * 1e3, found.max_s * 1e3, found.period_s * 1e3));
}

double ClockRecovery::wrap_half_period(double d) const { return d - period_s_ * std::round(d / period_s_); }

void ClockRecovery::follow_phase() {
    if (!have_ref_phase_) {
        ref_phase_s_ = phase_s_;
        have_ref_phase_ = true;
        return;
    }
    ref_phase_s_ += 0.1 * wrap_half_period(phase_s_ - ref_phase_s_);
}

// The tick a reading shows. Close to a tick of the estimated grid, time-stamp jitter alone
// cannot tell whether the CNC had already latched; the neighbours decide: the candidate tick
// at which the reading lies on the line between its neighbours wins.
double ClockRecovery::tick_of(std::size_t k) const {
    const PosRead& r = pending_[k];
    const double g = tick_at_or_before(r.t_s, period_s_, phase_s_);
    if (period_s_ <= 0 || !last_tick_ || k + 1 >= pending_.size()) return g;
    const double frac = (r.t_s - g) / period_s_;
    if (frac > 0.25 && frac < 0.75) return g;
    const double alt = frac <= 0.25 ? g - period_s_ : g + period_s_;
    const Tick& a = *last_tick_;
    const PosRead& b = pending_[k + 1];
    const double gb = tick_at_or_before(b.t_s, period_s_, phase_s_);
    if (!(a.t_s < alt && alt < gb) || !(a.t_s < g && g < gb)) return g;
    auto miss = [&](double c) {
        const double u = (c - a.t_s) / (gb - a.t_s);
        double m2 = 0;
        for (int ax = 0; ax < 3; ++ax) {
            const double d = r.p_mm[ax] - (a.p_mm[ax] + (b.p_mm[ax] - a.p_mm[ax]) * u);
            const double d_rot = r.rot_deg[ax] - (a.rot_deg[ax] + (b.rot_deg[ax] - a.rot_deg[ax]) * u);
            m2 += d * d + (d_rot * kRotaryMmPerDeg) * (d_rot * kRotaryMmPerDeg);
        }
        return m2;
    };
    return miss(alt) < miss(g) ? alt : g;
}

void ClockRecovery::add_tick(double t_s, std::optional<double> stamp_s, const PosRead& r) {
    const double* p = r.p_mm;
    // Without a grid the stamps themselves are compared: two stamps a rounding apart stay apart.
    if (last_tick_ && (stamp_s ? *stamp_s <= last_tick_stamp_s_ : t_s <= last_tick_->t_s)) {
        Tick& last = *last_tick_;
        if (!moved(as_read(last), r)) return;  // same tick read twice
        if (period_s_ > 0) {
            // Two positions on one tick: the later reading saw the next update.
            t_s = last.t_s + period_s_;
        } else {
            diag_.warn("duplicate_time", 0, "two different positions with the same time stamp; the later kept");
            std::copy(p, p + 3, last.p_mm);
            std::copy(r.rot_deg, r.rot_deg + 3, last.rot_deg);
            Tick replace = last;
            replace.t_s = last_tick_stamp_s_;
            replace.replaces_previous = true;
            emit(replace);
            return;
        }
    }
    Tick k;
    k.t_s = t_s;
    std::copy(p, p + 3, k.p_mm);
    std::copy(r.rot_deg, r.rot_deg + 3, k.rot_deg);
    k.period_s = period_s_;
    last_tick_ = k;
    k.t_s = stamp_s ? *stamp_s : origin_s_ + t_s;
    last_tick_stamp_s_ = k.t_s;
    emit(k);
}

}  // namespace cutload::motion_io::detail
