// The ingest pipeline's driver: reader -> chain of stages -> sink (model, CSV, nothing).
#include "motion_io/motion_io.hpp"
#include "pipeline.hpp"
#include "stages/standard.hpp"
#include "stages/survey.hpp"

#include "textio/csv.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <unistd.h>

namespace cutload::motion_io {
namespace {

using detail::GridSample;
using detail::GridSink;

class ModelSink final : public GridSink {
public:
    explicit ModelSink(MotionModel& m) : m_(m) {}
    void begin_session() override { new_session_ = true; }
    void sample(const GridSample& s) override {
        if (new_session_) {
            m_.session_start.push_back(m_.size());
            new_session_ = false;
        }
        m_.t_s.push_back(s.t_s);
        m_.x_mm.push_back(s.p_mm[0]), m_.y_mm.push_back(s.p_mm[1]), m_.z_mm.push_back(s.p_mm[2]);
        m_.vx_mm_s.push_back(s.v_mm_s[0]), m_.vy_mm_s.push_back(s.v_mm_s[1]), m_.vz_mm_s.push_back(s.v_mm_s[2]);
        m_.spindle_rpm.push_back(s.spindle_rpm);
        m_.spindle_angle_deg.push_back(s.spindle_angle_deg);
        m_.block.push_back(s.block);
        m_.tool.push_back(s.tool);
        for (std::size_t k = 0; k < 3; ++k)
            if (s.rotary & (1u << k)) m_.rot_deg[k].push_back(s.rot_deg[k]), m_.rot_vel_deg_s[k].push_back(s.rot_vel_deg_s[k]);
    }

private:
    MotionModel& m_;
    bool new_session_ = true;
};

// Fills a piece of the model and hands it out each time it is full (ingest_in_pieces).
class PieceSink final : public GridSink {
public:
    PieceSink(std::size_t piece_samples, double step_s, const detail::BlockTable& blocks,
              const std::function<void(const MotionModel&, std::size_t)>& each)
        : piece_samples_(std::max<std::size_t>(piece_samples, 1)), blocks_(blocks), each_(each), fill_(piece_) {
        piece_.step_s = step_s;
    }
    void begin_session() override { fill_.begin_session(); }
    void sample(const GridSample& s) override {
        if (piece_.size() == piece_samples_) hand_out();
        fill_.sample(s);
    }
    // The rest, once the log is read.
    void hand_out() {
        if (piece_.size() == 0) return;
        const std::vector<std::string>& names = blocks_.names();
        piece_.block_names.insert(piece_.block_names.end(), names.begin() + std::ptrdiff_t(piece_.block_names.size()),
                                  names.end());
        each_(piece_, first_);
        first_ += piece_.size();
        for (auto* v : {&piece_.t_s, &piece_.x_mm, &piece_.y_mm, &piece_.z_mm, &piece_.vx_mm_s, &piece_.vy_mm_s,
                        &piece_.vz_mm_s, &piece_.spindle_rpm, &piece_.spindle_angle_deg})
            v->clear();
        piece_.block.clear();
        piece_.tool.clear();
        piece_.session_start.clear();
        for (std::size_t k = 0; k < 3; ++k) piece_.rot_deg[k].clear(), piece_.rot_vel_deg_s[k].clear();
    }

private:
    std::size_t piece_samples_;
    const detail::BlockTable& blocks_;
    const std::function<void(const MotionModel&, std::size_t)>& each_;
    MotionModel piece_;
    ModelSink fill_;
    std::size_t first_ = 0;
};

// Measures the motion on its way to the real sink, so inspect reports the same extent ingest builds.
class ExtentSink final : public GridSink {
public:
    ExtentSink(GridSink& next, MotionExtent& extent) : next_(next), extent_(extent) {}
    void begin_session() override { next_.begin_session(); }
    void sample(const GridSample& s) override {
        extent_.add(s.spindle_angle_deg);
        next_.sample(s);
    }

private:
    GridSink& next_;
    MotionExtent& extent_;
};

class NullSink final : public GridSink {
public:
    void sample(const GridSample&) override {}
};

// Hands each sample to a caller that looks at the motion as it passes (inspect with a visitor),
// until it says it has seen enough.
class VisitSink final : public GridSink {
public:
    explicit VisitSink(const std::function<bool(const MotionState&)>& each) : each_(each) {}
    void sample(const GridSample& s) override {
        if (done_) return;
        MotionState m;
        m.t_s = s.t_s;
        for (std::size_t k = 0; k < 3; ++k) {
            m.pos_mm[k] = s.p_mm[k], m.vel_mm_s[k] = s.v_mm_s[k];
            if (s.rotary & (1u << k)) m.rot_deg[k] = s.rot_deg[k], m.rot_vel_deg_s[k] = s.rot_vel_deg_s[k];
        }
        m.spindle_rpm = s.spindle_rpm, m.spindle_angle_deg = s.spindle_angle_deg;
        m.block = s.block, m.tool = s.tool;
        done_ = !each_(m);
    }

private:
    const std::function<bool(const MotionState&)>& each_;
    bool done_ = false;
};

class CsvSink final : public GridSink {
public:
    CsvSink(std::FILE* f, const detail::BlockTable& blocks) : f_(f), blocks_(blocks) {
        buf_.append(std::string_view("t_s,x_mm,y_mm,z_mm,feed_mm_min,spindle_rpm,spindle_angle_deg,block\n"));
    }
    void sample(const GridSample& s) override {
        const double feed = std::sqrt(s.v_mm_s[0] * s.v_mm_s[0] + s.v_mm_s[1] * s.v_mm_s[1] + s.v_mm_s[2] * s.v_mm_s[2]) * 60;
        fmt::format_to(std::back_inserter(buf_), "{:.6f},{:.4f},{:.4f},{:.4f},{:.2f},{:.2f},{:.3f},", s.t_s, s.p_mm[0],
                       s.p_mm[1], s.p_mm[2], feed, s.spindle_rpm, s.spindle_angle_deg);
        if (s.block >= 0) {
            field_.clear();
            textio::append_field(field_, blocks_.names()[static_cast<std::size_t>(s.block)]);
            buf_.append(field_);
        }
        buf_.push_back('\n');
        ++rows_;
        if (buf_.size() > (1 << 20)) flush();
    }
    void flush() {
        if (std::fwrite(buf_.data(), 1, buf_.size(), f_) != buf_.size()) throw std::runtime_error("write failed");
        buf_.clear();
    }
    std::size_t rows() const { return rows_; }

private:
    std::FILE* f_;
    const detail::BlockTable& blocks_;
    fmt::memory_buffer buf_;
    std::string field_;
    std::size_t rows_ = 0;
};

// The feed channel's unit cannot be read from the numbers alone, but its integral over time must
// match the distance the positions travel. A clear mismatch is reported with the likely cause;
// the values are never rescaled without --feed-units.
void check_feed_unit(double ratio, detail::Diagnostics& diag) {
    if (ratio == 0 || (ratio > 0.5 && ratio < 2.0)) return;
    struct Cause {
        double ratio;
        const char* hint;
    };
    static const Cause causes[] = {
        {60.0, "per-minute values read as per-second: try --feed-units mm/min"},
        {1 / 60.0, "per-second values read as per-minute: try --feed-units mm/s"},
        // The feed's values as read are 25.4 x the motion's: mm values read as inch (and back).
        {25.4, "mm values read as inch: try --feed-units mm/min"},
        {1 / 25.4, "inch values read as mm: try --feed-units in/min"}};
    std::string hint = "check the feed channel's unit (--feed-units)";
    for (const Cause& c : causes)
        if (std::fabs(std::log(ratio / c.ratio)) < std::log(1.5)) hint = c.hint;
    diag.warn("feed_unit_suspect", 0,
              fmt::format("feed channel integrates to {:.1f} x the path length of the positions; {}", ratio, hint));
}

// When glitches were dropped, a failure for missing data says so (every reading may have been
// one: a unit far off).
std::string glitch_hint(std::string what, const detail::Diagnostics& diag) {
    for (const IngestWarning& w : diag.warnings())
        if (w.code == "glitch_dropped") what += fmt::format("; {} reading(s) dropped as glitches: {}", w.count, w.message);
    return what;
}

IngestReport run_pipeline(const std::string& path, const ReadOptions& opt, GridSink& sink,
                          detail::BlockTable& blocks) {
    // Below 0.01 ms the output grows without bound for no gain (a CNC updates every 1-8 ms);
    // 1 s is already coarser than an event-driven MTConnect log's own sampling.
    if (!(opt.step_ms >= 0.01 && opt.step_ms <= 1000))
        throw IngestError(fmt::format("step must be from 0.01 to 1000 ms, got {}", opt.step_ms));
    detail::Diagnostics diag(path);
    const Format format = opt.format == Format::Auto ? detail::detect_format(path, diag) : opt.format;
    detail::ChainSettings settings;
    settings.step_s = opt.step_ms * 1e-3;
    settings.event_driven = format == Format::Shdr;
    settings.clock.scan_threads = std::clamp(opt.threads, 1u, 2u);
    MotionExtent extent;
    ExtentSink measured(sink, extent);
    const auto chain = detail::make_ingest_chain(diag, measured, settings);
    if (format == Format::Csv)
        detail::read_csv(path, opt, diag, blocks, *chain);
    else
        detail::read_shdr(path, opt, diag, blocks, *chain);
    const auto* survey = chain->find_as<detail::Survey>("survey");
    if (survey->position_reads() == 0)
        diag.fail(0, glitch_hint("no position samples (CSV: columns x, y, z; SHDR: a path-position or axis key)", diag));

    IngestReport report;
    chain->fill_report(report);
    detail::report_reader_facts(diag, report);
    if (!report.channels.count("spindle"))
        diag.warn("no_spindle", 0, "no spindle speed channel: speed 0 rpm assumed");
    check_feed_unit(survey->feed_to_path_ratio(), diag);
    report.file = path;
    report.format = format == Format::Csv ? "csv" : "shdr";
    report.blocks = blocks.names().size();
    report.extent = extent;
    report.warnings = diag.warnings();
    return report;
}

}  // namespace

MotionExtent motion_extent(const MotionModel& m) {
    MotionExtent e;
    for (double a : m.spindle_angle_deg) e.add(a);
    return e;
}

MotionModel ingest(const std::string& path, const ReadOptions& opt, IngestReport* report) {
    MotionModel m;
    m.step_s = opt.step_ms * 1e-3;
    ModelSink sink(m);
    detail::BlockTable blocks;
    IngestReport r = run_pipeline(path, opt, sink, blocks);
    m.block_names = blocks.names();
    if (!r.channels.count("tool")) m.tool.clear();   // no tool channel: empty, not all -1
    if (report) *report = std::move(r);
    return m;
}

IngestReport inspect(const std::string& path, const ReadOptions& opt) {
    NullSink sink;
    detail::BlockTable blocks;
    return run_pipeline(path, opt, sink, blocks);
}

IngestReport inspect(const std::string& path, const ReadOptions& opt, const std::function<bool(const MotionState&)>& each_sample) {
    VisitSink sink(each_sample);
    detail::BlockTable blocks;
    return run_pipeline(path, opt, sink, blocks);
}

IngestReport ingest_in_pieces(const std::string& path, const ReadOptions& opt, std::size_t piece_samples,
                              const std::function<void(const MotionModel& piece, std::size_t first_sample)>& each_piece,
                              std::vector<std::string>* block_names) {
    detail::BlockTable blocks;
    PieceSink sink(piece_samples, opt.step_ms * 1e-3, blocks, each_piece);
    IngestReport r = run_pipeline(path, opt, sink, blocks);
    sink.hand_out();
    if (block_names) *block_names = blocks.names();
    return r;
}

std::size_t resample_to_csv(const std::string& path, const ReadOptions& opt, const std::string& out_csv,
                            IngestReport* report) {
    // Written next to the target and renamed at the end, so a failure leaves no partial file.
    const std::string tmp = fmt::format("{}.tmp{}", out_csv, static_cast<long>(::getpid()));
    std::FILE* f = std::fopen(tmp.c_str(), "wb");
    if (!f) throw std::runtime_error(fmt::format("{}: cannot create output file", out_csv));
    try {
        detail::BlockTable blocks;
        CsvSink sink(f, blocks);
        IngestReport r = run_pipeline(path, opt, sink, blocks);
        sink.flush();
        if (std::fclose(f) != 0) {
            f = nullptr;
            throw std::runtime_error(fmt::format("{}: write failed", out_csv));
        }
        f = nullptr;
        std::filesystem::rename(tmp, out_csv);
        if (report) *report = std::move(r);
        return sink.rows();
    } catch (...) {
        if (f) std::fclose(f);
        std::error_code ec;
        std::filesystem::remove(tmp, ec);
        throw;
    }
}

}  // namespace cutload::motion_io
