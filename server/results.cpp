#include "results.hpp"

#include "program.hpp"
#include "series.hpp"
#include "db/library.hpp"
#include "db/runs.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <iterator>
#include <map>
#include <set>
#include <stdexcept>

namespace cutload::server {
namespace fs = std::filesystem;
namespace {

json block_json(std::size_t idx, const force_model::BlockSummary& b) {
    json flags = json::array();
    // Tools by T number; null where none is named (a run spec without a tool table on a log
    // without a tool channel).
    auto tool = [](std::int32_t t) { return t >= 0 ? json(t) : json(nullptr); };
    for (const auto& f : b.flags)
        flags.push_back({{"flag", f.flag}, {"t_s", f.t_s}, {"value", f.value}, {"tool", tool(f.tool)}});
    return {{"idx", idx},
            {"block", b.block},
            {"tool", tool(b.tool)},
            {"t_start_s", b.t_start_s},
            {"t_end_s", b.t_end_s},
            {"peak_force_N", b.peak_force_N},
            {"mean_force_N", b.mean_force_N},
            {"peak_torque_Nm", b.peak_torque_Nm},
            {"peak_power_kW", b.peak_power_kW},
            {"max_chip_mm", b.max_chip_mm},
            {"max_bending_MPa", b.max_bending_MPa},
            {"max_radial_engagement_mm", b.max_radial_engagement_mm},
            {"max_axial_engagement_mm", b.max_axial_engagement_mm},
            {"removed_mm3", b.removed_mm3},
            {"flags", flags}};
}


// The series rows go into the builder as they are made: a SeriesData of the whole motion first
// would hold 32 bytes a sample (about 120 MB for an hour at 1 ms) at the end of every run.
void add_motion_rows(SeriesBuilder& b, const motion_io::MotionModel& m) {
    for (std::size_t i = 0; i < m.size(); ++i) {
        const double v = std::sqrt(m.vx_mm_s[i] * m.vx_mm_s[i] + m.vy_mm_s[i] * m.vy_mm_s[i] + m.vz_mm_s[i] * m.vz_mm_s[i]);
        const float row[] = {static_cast<float>(m.x_mm[i]), static_cast<float>(m.y_mm[i]), static_cast<float>(m.z_mm[i]),
                             static_cast<float>(v * 60.0), static_cast<float>(m.spindle_rpm[i]),
                             static_cast<float>(m.block[i])};
        static_assert(std::size(row) == 6);
        b.add(m.t_s[i], row);
    }
}

void write_motion_series(db::RunRepository& runs, std::int64_t run_id, const motion_io::MotionModel& m) {
    SeriesBuilder b(SeriesId::Motion, store_chunks(runs, run_id));
    add_motion_rows(b, m);
    b.finish();
}

// A turning tool's axis per motion sample, on the motion's times.
void write_tool_axis_series(db::RunRepository& runs, std::int64_t run_id, const motion_io::MotionModel& m,
                            std::span<const std::array<float, 3>> axis) {
    if (axis.size() != m.size())
        throw std::invalid_argument(fmt::format("a tool axis for {} motion samples, not {}", axis.size(), m.size()));
    SeriesBuilder b(SeriesId::ToolAxis, store_chunks(runs, run_id));
    for (std::size_t i = 0; i < m.size(); ++i) b.add(m.t_s[i], axis[i].data());
    b.finish();
}

struct RunRefs {
    std::optional<std::int64_t> machine_id, tool_id, material_id;
    std::optional<std::string> name, program;
    std::optional<double> spindle_power_kW;
};

RunRefs load_refs(db::Session& s, std::int64_t run_id) {
    RunRefs r;
    const auto run = s.runs().get(run_id);
    if (!run) return r;
    r.machine_id = run->machine_id;
    r.tool_id = run->tool_id;
    r.material_id = run->material_id;
    r.name = run->name;
    r.program = run->program;
    if (r.machine_id)
        if (const auto m = s.library().get(db::LibraryKind::Machine, *r.machine_id))
            r.spindle_power_kW = json::parse(m->body_json).value("spindle_power_kW", 0.0);
    return r;
}

std::optional<double> metric_value(const std::string& metric, const force_model::BlockSummary& b, const RunRefs& refs) {
    if (metric == "peak_force_N") return b.peak_force_N;
    if (metric == "peak_torque_Nm") return b.peak_torque_Nm;
    if (metric == "peak_power_kW") return b.peak_power_kW;
    if (metric == "max_chip_mm") return b.max_chip_mm;
    if (metric == "max_bending_MPa") return b.max_bending_MPa;
    if (metric == "power_pct") {
        if (!refs.spindle_power_kW || *refs.spindle_power_kW <= 0) return std::nullopt;
        return 100.0 * b.peak_power_kW / *refs.spindle_power_kW;
    }
    return std::nullopt;
}

// Flags that mean a collision rather than a load over its limit: their alerts are critical.
bool collision_flag(const std::string& flag) { return flag == "rapid_in_material" || flag == "holder_contact"; }

}  // namespace

void force_row(const force_model::ForceSample& s, const std::vector<std::int32_t>& block_of, float* row) {
    const float f = std::sqrt(s.fx_N * s.fx_N + s.fy_N * s.fy_N + s.fz_N * s.fz_N);
    // Wrapped: the unwrapped angle of a long run exceeds float precision.
    const auto angle = static_cast<float>(std::fmod(s.spindle_angle_deg, 360.0));
    const std::int32_t block =
        s.block >= 0 && static_cast<std::size_t>(s.block) < block_of.size() ? block_of[static_cast<std::size_t>(s.block)] : s.block;
    const float values[] = {angle < 0 ? angle + 360.0f : angle, static_cast<float>(block), s.fx_N, s.fy_N, s.fz_N, f,
                            s.torque_Nm, s.power_kW, s.chip_mm, s.bending_MPa, s.radial_engagement_mm,
                            s.axial_engagement_mm};
    std::copy(std::begin(values), std::end(values), row);
}

SeriesData force_series(const force_model::Prediction& p, const std::vector<std::int32_t>& block_of) {
    SeriesData d;
    const std::size_t k = series_channels(SeriesId::Forces).size();
    d.t_s.reserve(p.samples.size());
    d.values.resize(p.samples.size() * k);
    for (std::size_t i = 0; i < p.samples.size(); ++i) {
        d.t_s.push_back(p.samples[i].t_s);
        force_row(p.samples[i], block_of, &d.values[i * k]);
    }
    return d;
}


// Evaluates every enabled threshold that applies to this run; inserts alerts and deliveries.
// `limit_alerts`: a run whose blocks the engine flagged against the run's own limits raises an
// alert of its own (threshold_id null, "run limits") for the flags that no enabled flag threshold
// applying to the run covers already (an "any flag" threshold covers all).
int raise_alerts(db::Session& s, std::int64_t run_id, const force_model::Prediction& p, bool limit_alerts) {
    const RunRefs refs = load_refs(s, run_id);
    const std::vector<std::int64_t> hook_ids = s.webhooks().enabled_ids();

    int raised = 0;
    // One rule over the run's blocks; inserts its alert when it trips.
    // `covered`: flags left out (those other rules raise alerts for).
    auto evaluate = [&](std::optional<std::int64_t> threshold_id, const std::string& name, const std::string& metric,
                        const std::string& flag, double limit, std::optional<std::string> severity,
                        const std::set<std::string>& covered = {}) {
        json blocks = json::array();
        double worst = 0;
        std::size_t hits = 0;
        bool collision = false;
        for (const auto& b : p.blocks) {
            std::optional<double> v;
            if (metric == "flag") {
                for (const auto& f : b.flags)
                    if ((flag == "any" || f.flag == flag) && !covered.count(f.flag)) {
                        if (!v) v = f.value;
                        collision = collision || collision_flag(f.flag);
                    }
            } else if (auto x = metric_value(metric, b, refs); x && *x > limit) {
                v = x;
            }
            if (!v) continue;
            if (hits == 0 || *v > worst) worst = *v;
            // The alert lists the first blocks; the count says how many there were.
            if (++hits <= 50)
                blocks.push_back({{"block", b.block}, {"tool", b.tool >= 0 ? json(b.tool) : json(nullptr)},
                                  {"t_start_s", b.t_start_s}, {"value", *v}});
        }
        if (hits == 0) return;

        const std::string first = blocks[0]["block"].get<std::string>();
        std::string message =
            !threshold_id ? fmt::format("run {}: {} block(s) over the run's own limits{}, first {}", run_id, hits,
                                        collision ? " (with a collision)" : "", first)
            : metric == "flag"
                ? fmt::format("run {}: flag {} in {} block(s), first {}", run_id, flag, hits, first)
                : fmt::format("run {}: {} {:.4g} over the limit {:.4g} in {} block(s), first {}", run_id, metric, worst,
                              limit, hits, first);
        json body{{"threshold_name", name},
                  {"metric", metric},
                  {"flag", metric == "flag" ? json(flag) : json(nullptr)},
                  {"limit", metric == "flag" ? json(nullptr) : json(limit)},
                  {"value", worst},
                  {"block_count", hits},
                  {"blocks", blocks},
                  {"message", message}};
        const std::string now = db::now_iso();
        const std::int64_t alert_id = s.alerts().create(
            run_id, threshold_id, severity.value_or(collision ? "critical" : "warning"), body.dump(), now);
        ++raised;

        const json payload{{"event", "alert.raised"}, {"alert", load_alert(s, alert_id)}};
        for (auto hook : hook_ids) s.webhooks().enqueue(hook, alert_id, payload.dump(), unix_now_s(), now);
    };

    std::set<std::string> covered;   // flags that applicable flag thresholds raise alerts for
    for (const db::ThresholdRecord& rule : s.thresholds().enabled()) {
        auto matches = [&](const std::optional<std::int64_t>& scoped, const std::optional<std::int64_t>& ref) {
            return ref && scoped && *scoped == *ref;
        };
        if ((rule.scope == "machine" && !matches(rule.machine_id, refs.machine_id)) ||
            (rule.scope == "tool" && !matches(rule.tool_id, refs.tool_id)) ||
            (rule.scope == "material" && !matches(rule.material_id, refs.material_id)))
            continue;
        const std::string flag = rule.flag.value_or("any");
        if (rule.metric == "flag") {
            if (flag == "any")
                covered.insert(known_flags().begin(), known_flags().end());
            else
                covered.insert(flag);
        }
        evaluate(rule.id, rule.name, rule.metric, flag, rule.limit.value_or(0), rule.severity);
    }
    // A tool the run spec lacks is not a limit: its blocks are flagged (and a threshold on the flag
    // unknown_tool can alert), but the run-limits alert stays about limits.
    covered.insert("unknown_tool");
    if (limit_alerts) evaluate(std::nullopt, "run limits", "flag", "any", 0, std::nullopt, covered);
    return raised;
}

namespace {

json summary_json(const force_model::Prediction& p, double final_volume_mm3, std::size_t rows) {
    double peak_f = 0, peak_t = 0, peak_p = 0, chip = 0, bend = 0, removed = 0;
    std::size_t flagged = 0;
    std::map<std::string, int> flag_counts;
    for (const auto& b : p.blocks) {
        peak_f = std::max(peak_f, b.peak_force_N);
        peak_t = std::max(peak_t, b.peak_torque_Nm);
        peak_p = std::max(peak_p, b.peak_power_kW);
        chip = std::max(chip, b.max_chip_mm);
        bend = std::max(bend, b.max_bending_MPa);
        removed += b.removed_mm3;
        if (!b.flags.empty()) ++flagged;
        for (const auto& f : b.flags) ++flag_counts[f.flag];
    }
    return {{"samples", rows},
            {"blocks", p.blocks.size()},
            {"flagged_blocks", flagged},
            {"flags", flag_counts},
            {"peak_force_N", peak_f},
            {"peak_torque_Nm", peak_t},
            {"peak_power_kW", peak_p},
            {"max_chip_mm", chip},
            {"max_bending_MPa", bend},
            {"removed_mm3", removed},
            {"final_stock_volume_mm3", final_volume_mm3},
            {"simulated_s", p.stats.simulated_s},
            {"compute_s", p.stats.wall_s},
            {"steps", p.stats.steps},
            {"cutting_steps", p.stats.cutting_steps},
            {"device", p.stats.device}};
}

}  // namespace

const std::vector<std::string>& threshold_metrics() {
    static const std::vector<std::string> m{"peak_force_N", "peak_torque_Nm", "peak_power_kW", "power_pct",
                                            "max_chip_mm",  "max_bending_MPa", "flag"};
    return m;
}

const std::vector<std::string>& known_flags() {
    static const std::vector<std::string> f{"any",           "force_limit",       "torque_limit",  "power_limit",
                                            "chip_load_limit", "bending_limit", "rapid_in_material", "holder_contact",
                                            "holder_near_miss", "unknown_tool"};
    return f;
}

json alert_json(const db::AlertRecord& a) {
    json j = json::parse(a.body_json);
    j["id"] = a.id;
    j["run_id"] = a.run_id;
    j["threshold_id"] = or_null(a.threshold_id);
    j["severity"] = a.severity;
    j["created_at"] = a.created_at;
    j["acked_at"] = or_null(a.acked_at);
    j["acked_by"] = or_null(a.acked_by);
    j["ack_note"] = or_null(a.ack_note);
    j["run"] = {{"name", or_null(a.run_name)}, {"program", or_null(a.run_program)}, {"machine_id", or_null(a.run_machine_id)}};
    return j;
}

json load_alert(db::Session& s, std::int64_t alert_id) {
    const auto a = s.alerts().get(alert_id);
    return a ? alert_json(*a) : json(nullptr);
}

namespace {

// store_result and store_live_result: `alerts_raised` set means the alerts were raised already.
int store_run(db::Session& s, std::int64_t run_id, const motion_io::MotionModel& motion, const force_model::Prediction& p,
              const ProgramResult* program, bool limit_alerts,
              std::optional<int> alerts_raised, const json* live, const std::atomic<bool>* cancel,
              ForceSeriesSpool* forces = nullptr, const json* kinematics = nullptr,
              std::span<const std::array<float, 3>> tool_axis = {}) {
    db::Transaction tx(s);
    // Cancelled or deleted while computing: nothing to store.
    const auto status = s.runs().status(run_id);
    if (!status || status->state != db::JobState::Running) return 0;
    db::RunRepository& runs = s.runs();
    bool flagged = false;
    for (std::size_t i = 0; i < p.blocks.size(); ++i) {
        runs.add_block(run_id, static_cast<std::int64_t>(i), block_json(i, p.blocks[i]).dump(), !p.blocks[i].flags.empty());
        flagged = flagged || !p.blocks[i].flags.empty();
    }
    if (forces) {
        forces->replay(runs, run_id);
        // Gone before the run is seen done: a rollback after this fails the job, whose retry
        // writes a new spool.
        forces->remove_file();
    }
    else write_series(runs, run_id, SeriesId::Forces, force_series(p));
    if (!(forces && forces->holds_motion())) write_motion_series(runs, run_id, motion);
    if (!tool_axis.empty()) write_tool_axis_series(runs, run_id, motion, tool_axis);
    // Written into the store as it is serialised (db::RunRepository::set_final_stock).
    if (p.final_stock)
        runs.set_final_stock(run_id, force_model::stock_file_bytes(*p.final_stock),
                             [&](std::ostream& out) { force_model::save_stock(*p.final_stock, out); });
    const int alerts = alerts_raised ? *alerts_raised : raise_alerts(s, run_id, p, limit_alerts);
    json summary = summary_json(p, p.final_stock ? force_model::stock_volume_mm3(*p.final_stock) : 0.0,
                                forces ? forces->rows() : p.samples.size());
    summary["alerts"] = alerts;
    if (live) summary["live"] = *live;
    if (kinematics) summary["kinematics"] = *kinematics;
    std::vector<std::string> names = p.block_names.empty() ? motion.block_names : p.block_names;
    if (program) {
        // The commanded series names its blocks in the run's list, so one block_names serves both.
        const force_model::Prediction& cmd = program->prediction.commanded;
        std::vector<std::int32_t> block_of;
        for (const std::string& name : cmd.block_names) {
            auto at = std::find(names.begin(), names.end(), name);
            if (at == names.end()) at = names.insert(names.end(), name);
            block_of.push_back(static_cast<std::int32_t>(at - names.begin()));
        }
        // On the actual run's time axis, block by block, so the two traces line up in one plot.
        SeriesData cmd_series = force_series(cmd, block_of);
        for (double& t : cmd_series.t_s) t = program->prediction.to_actual_time(t);
        write_series(runs, run_id, SeriesId::CommandedForces, cmd_series);
        const json commanded_summary =
            summary_json(cmd, cmd.final_stock ? force_model::stock_volume_mm3(*cmd.final_stock) : 0.0, cmd.samples.size());
        runs.set_program_body(run_id, program_body(*program, commanded_summary).dump());
        const auto& q = program->run.mapping.quality;
        summary["program"] = {{"program_blocks", program->run.program.blocks.size()},
                              {"mapped", program->run.mapped},
                              {"matched_fraction", q.matched_fraction},
                              {"commanded_peak_force_N", commanded_summary["peak_force_N"]},
                              {"commanded_simulated_s", cmd.stats.simulated_s}};
    }
    runs.mark_done(run_id, summary.dump(), json(names).dump(), flagged || alerts > 0, db::now_iso());
    if (cancel && cancel->load()) throw force_model::Cancelled();   // the transaction rolls back
    tx.commit();
    return alerts;
}

}  // namespace

int store_result(db::Session& s, std::int64_t run_id, const motion_io::MotionModel& motion,
                 const force_model::Prediction& p, const ProgramResult* program, bool limit_alerts,
                 const std::atomic<bool>* cancel, ForceSeriesSpool* forces, const json* kinematics,
                 std::span<const std::array<float, 3>> tool_axis) {
    return store_run(s, run_id, motion, p, program, limit_alerts, std::nullopt, nullptr, cancel, forces,
                     kinematics, tool_axis);
}

json kinematics_summary(const std::array<double, 3>& tool_axis, double tool_lean_deg, bool fixed_tilt, bool turning) {
    return {{"tool_axis", tool_axis}, {"tool_lean_deg", tool_lean_deg}, {"fixed_tilt", fixed_tilt}, {"turning", turning}};
}

namespace {

// A spooled chunk: its SeriesChunkInfo and blob size, then the blob.
struct SpoolHeader {
    std::int32_t series = 0, level = 0;
    std::int64_t chunk = 0;
    double t0_s = 0, t1_s = 0;
    std::int64_t n = 0;
    std::uint64_t bytes = 0;
};

}  // namespace

int force_series_first_level(double expected_rows, double max_raw_rows) {
    int level = 0;
    while (max_raw_rows > 0 && expected_rows > max_raw_rows) {
        expected_rows /= static_cast<double>(kFanout);
        ++level;
    }
    return level;
}

ChunkSpool::ChunkSpool(fs::path file, SeriesId series, int first_level)
    : file_(std::move(file)), out_(file_, std::ios::binary | std::ios::trunc),
      builder_(series,
               [this](const db::SeriesChunkInfo& info, std::span<const unsigned char> blob) {
                   const SpoolHeader h{info.series, info.level, info.chunk, info.t0_s, info.t1_s, info.n, blob.size()};
                   out_.write(reinterpret_cast<const char*>(&h), sizeof h);
                   out_.write(reinterpret_cast<const char*>(blob.data()), static_cast<std::streamsize>(blob.size()));
                   if (!out_) throw std::runtime_error("cannot write the series spool " + file_.string());
                   bytes_ += sizeof h + blob.size();
               },
               first_level) {
    if (!out_) throw std::runtime_error("cannot write the series spool " + file_.string());
}

ChunkSpool::~ChunkSpool() { remove_file(); }

void ChunkSpool::remove_file() {
    out_.close();
    std::error_code ec;
    fs::remove(file_, ec);
}

void ChunkSpool::finish() {
    builder_.finish();
    out_.flush();
    if (!out_) throw std::runtime_error("cannot write the series spool " + file_.string());
    out_.close();
}

void ChunkSpool::replay(db::RunRepository& runs, std::int64_t run_id) const {
    std::ifstream in(file_, std::ios::binary);
    if (!in) throw std::runtime_error("cannot read the series spool " + file_.string());
    SpoolHeader h;
    std::vector<unsigned char> blob;
    while (in.read(reinterpret_cast<char*>(&h), sizeof h)) {
        // A chunk holds kChunkElems elements (under 1 MB); a header past 1 GiB is not one this wrote.
        if (h.bytes > (std::uint64_t(1) << 30))
            throw std::runtime_error(fmt::format("the series spool {} is corrupt: a chunk of {} bytes", file_.string(), h.bytes));
        blob.resize(h.bytes);
        if (!in.read(reinterpret_cast<char*>(blob.data()), static_cast<std::streamsize>(h.bytes)))
            throw std::runtime_error("the series spool " + file_.string() + " ends inside a chunk");
        runs.add_series_chunk(run_id, db::SeriesChunkInfo{h.series, h.level, h.chunk, h.t0_s, h.t1_s, h.n}, blob);
    }
}

ForceSeriesSpool::ForceSeriesSpool(fs::path file, int first_level)
    : file_(std::move(file)), forces_(file_, SeriesId::Forces, first_level), first_level_(first_level) {}

void ForceSeriesSpool::add_motion(const motion_io::MotionModel& piece) {
    if (!motion_) {
        fs::path motion_file = file_;
        motion_file.replace_extension(".motion.spool");
        motion_.emplace(motion_file, SeriesId::Motion);
    }
    add_motion_rows(motion_->builder(), piece);
}

void ForceSeriesSpool::remove_file() {
    forces_.remove_file();
    if (motion_) motion_->remove_file();
}

void ForceSeriesSpool::add(std::span<const force_model::ForceSample> rows) {
    float row[12];
    static_assert(sizeof row / sizeof row[0] == 12, "forces series channels");
    for (const force_model::ForceSample& r : rows) {
        force_row(r, {}, row);
        forces_.builder().add(r.t_s, row);
    }
}

void ForceSeriesSpool::finish() {
    forces_.finish();
    if (motion_) motion_->finish();
}

std::size_t ForceSeriesSpool::rows() const { return forces_.builder().rows(); }

void ForceSeriesSpool::replay(db::RunRepository& runs, std::int64_t run_id) const {
    forces_.replay(runs, run_id);
    if (motion_) motion_->replay(runs, run_id);
}

json block_summary_json(std::size_t idx, const force_model::BlockSummary& b) { return block_json(idx, b); }

int store_live_result(db::Session& s, std::int64_t run_id, const motion_io::MotionModel& motion,
                      const force_model::Prediction& p, int alerts_raised, const json& live) {
    return store_run(s, run_id, motion, p, nullptr, false, alerts_raised, &live, nullptr);
}

}  // namespace cutload::server
