#include "results.hpp"

#include "program.hpp"
#include "series.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <set>

namespace cutload::server {
namespace {

json block_json(std::size_t idx, const force_model::BlockSummary& b) {
    json flags = json::array();
    for (const auto& f : b.flags) flags.push_back({{"flag", f.flag}, {"t_s", f.t_s}, {"value", f.value}});
    return {{"idx", idx},
            {"block", b.block},
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

// `block_of` maps the prediction's block indices to the stored block names (identity: empty).
SeriesData force_series(const force_model::Prediction& p, const std::vector<std::int32_t>& block_of = {}) {
    SeriesData d;
    const std::size_t k = series_channels(SeriesId::Forces).size();
    d.t_s.reserve(p.samples.size());
    d.values.reserve(p.samples.size() * k);
    for (const auto& s : p.samples) {
        d.t_s.push_back(s.t_s);
        const float f = std::sqrt(s.fx_N * s.fx_N + s.fy_N * s.fy_N + s.fz_N * s.fz_N);
        // Wrapped: the unwrapped angle of a long run exceeds float precision.
        const auto angle = static_cast<float>(std::fmod(s.spindle_angle_deg, 360.0));
        const std::int32_t block =
            s.block >= 0 && static_cast<std::size_t>(s.block) < block_of.size() ? block_of[static_cast<std::size_t>(s.block)] : s.block;
        const float row[] = {angle < 0 ? angle + 360.0f : angle, static_cast<float>(block), s.fx_N, s.fy_N, s.fz_N, f,
                             s.torque_Nm, s.power_kW, s.chip_mm, s.bending_MPa, s.radial_engagement_mm,
                             s.axial_engagement_mm};
        d.values.insert(d.values.end(), std::begin(row), std::end(row));
    }
    return d;
}

SeriesData motion_series(const motion_io::MotionModel& m) {
    SeriesData d;
    d.t_s = m.t_s;
    d.values.reserve(m.size() * series_channels(SeriesId::Motion).size());
    for (std::size_t i = 0; i < m.size(); ++i) {
        const double v = std::sqrt(m.vx_mm_s[i] * m.vx_mm_s[i] + m.vy_mm_s[i] * m.vy_mm_s[i] + m.vz_mm_s[i] * m.vz_mm_s[i]);
        const float row[] = {static_cast<float>(m.x_mm[i]), static_cast<float>(m.y_mm[i]), static_cast<float>(m.z_mm[i]),
                             static_cast<float>(v * 60.0), static_cast<float>(m.spindle_rpm[i]),
                             static_cast<float>(m.block[i])};
        d.values.insert(d.values.end(), std::begin(row), std::end(row));
    }
    return d;
}

struct RunRefs {
    std::optional<std::int64_t> machine_id, tool_id, material_id;
    std::optional<std::string> name, program;
    std::optional<double> spindle_power_kW;
};

RunRefs load_refs(db::Connection& c, std::int64_t run_id) {
    RunRefs r;
    auto st = c.prepare(
        "SELECT r.machine_id, r.tool_id, r.material_id, r.name, r.program, m.body FROM runs r "
        "LEFT JOIN machines m ON m.id = r.machine_id WHERE r.id = ?");
    st.bind(1, run_id);
    if (!st.step()) return r;
    r.machine_id = st.opt_i64(0);
    r.tool_id = st.opt_i64(1);
    r.material_id = st.opt_i64(2);
    r.name = st.opt_text(3);
    r.program = st.opt_text(4);
    if (!st.is_null(5)) r.spindle_power_kW = json::parse(st.text(5)).value("spindle_power_kW", 0.0);
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

// Evaluates every enabled threshold that applies to this run; inserts alerts and deliveries.
// `limit_alerts`: a run whose blocks the engine flagged against the run's own limits raises an
// alert of its own (threshold_id null, "run limits") for the flags that no enabled flag threshold
// applying to the run covers already (an "any flag" threshold covers all).
int raise_alerts(db::Connection& c, std::int64_t run_id, const force_model::Prediction& p, bool limit_alerts) {
    const RunRefs refs = load_refs(c, run_id);
    auto rules = c.prepare(
        "SELECT id, name, scope, machine_id, tool_id, material_id, metric, flag, limit_value, severity "
        "FROM thresholds WHERE enabled = 1 ORDER BY id");
    auto ins = c.prepare("INSERT INTO alerts(run_id, threshold_id, severity, body, created_at) VALUES (?,?,?,?,?)");
    auto hooks = c.prepare("SELECT id FROM webhooks WHERE enabled = 1");
    auto deliver = c.prepare(
        "INSERT INTO webhook_deliveries(webhook_id, alert_id, payload, state, attempts, next_attempt_unix, created_at) "
        "VALUES (?,?,?,'pending',0,?,?)");
    std::vector<std::int64_t> hook_ids;
    while (hooks.step()) hook_ids.push_back(hooks.i64(0));

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
            if (++hits <= 50) blocks.push_back({{"block", b.block}, {"t_start_s", b.t_start_s}, {"value", *v}});
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
        ins.reset();
        ins.bind(1, run_id).bind(2, threshold_id).bind(3, severity.value_or(collision ? "critical" : "warning"));
        ins.bind(4, body.dump()).bind(5, now).run();
        const std::int64_t alert_id = c.last_insert_id();
        ++raised;

        const json payload{{"event", "alert.raised"}, {"alert", load_alert(c, alert_id)}};
        for (auto hook : hook_ids) {
            deliver.reset();
            deliver.bind(1, hook).bind(2, alert_id).bind(3, payload.dump()).bind(4, unix_now_s()).bind(5, now).run();
        }
    };

    std::set<std::string> covered;   // flags that applicable flag thresholds raise alerts for
    while (rules.step()) {
        const std::string scope = rules.text(2);
        auto matches = [&](int col, const std::optional<std::int64_t>& ref) {
            return ref && !rules.is_null(col) && rules.i64(col) == *ref;
        };
        if ((scope == "machine" && !matches(3, refs.machine_id)) || (scope == "tool" && !matches(4, refs.tool_id)) ||
            (scope == "material" && !matches(5, refs.material_id)))
            continue;
        const std::string metric = rules.text(6);
        const std::string flag = rules.opt_text(7).value_or("any");
        if (metric == "flag") {
            if (flag == "any")
                covered.insert(known_flags().begin(), known_flags().end());
            else
                covered.insert(flag);
        }
        evaluate(rules.i64(0), rules.text(1), metric, flag, rules.opt_real(8).value_or(0), rules.text(9));
    }
    if (limit_alerts) evaluate(std::nullopt, "run limits", "flag", "any", 0, std::nullopt, covered);
    return raised;
}

json summary_json(const force_model::Prediction& p, double final_volume_mm3) {
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
    return {{"samples", p.samples.size()},
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
                                            "chip_load_limit", "bending_limit", "rapid_in_material", "holder_contact"};
    return f;
}

json load_alert(db::Connection& c, std::int64_t alert_id) {
    auto st = c.prepare(
        "SELECT a.id, a.run_id, a.threshold_id, a.severity, a.body, a.created_at, a.acked_at, a.acked_by, a.ack_note, "
        "r.name, r.program, r.machine_id FROM alerts a JOIN runs r ON r.id = a.run_id WHERE a.id = ?");
    st.bind(1, alert_id);
    if (!st.step()) return nullptr;
    return alert_row_json(st);
}

json alert_row_json(const db::Stmt& st) {
    json j = json::parse(st.text(4));
    j["id"] = st.i64(0);
    j["run_id"] = st.i64(1);
    j["threshold_id"] = st.is_null(2) ? json(nullptr) : json(st.i64(2));
    j["severity"] = st.text(3);
    j["created_at"] = st.text(5);
    j["acked_at"] = st.is_null(6) ? json(nullptr) : json(st.text(6));
    j["acked_by"] = st.is_null(7) ? json(nullptr) : json(st.text(7));
    j["ack_note"] = st.is_null(8) ? json(nullptr) : json(st.text(8));
    j["run"] = {{"name", st.is_null(9) ? json(nullptr) : json(st.text(9))},
                {"program", st.is_null(10) ? json(nullptr) : json(st.text(10))},
                {"machine_id", st.is_null(11) ? json(nullptr) : json(st.i64(11))}};
    return j;
}

int store_result(db::Connection& c, std::int64_t run_id, const motion_io::MotionModel& motion,
                 const force_model::Prediction& p, const std::string& stock_bytes, const ProgramResult* program,
                 bool limit_alerts) {
    db::Transaction tx(c);
    {
        auto st = c.prepare("SELECT state FROM runs WHERE id = ?");
        st.bind(1, run_id);
        // Cancelled or deleted while computing: nothing to store.
        if (!st.step() || st.text(0) != "running") return 0;
    }
    auto blk = c.prepare("INSERT INTO run_blocks(run_id, idx, body, flagged) VALUES (?,?,?,?)");
    bool flagged = false;
    for (std::size_t i = 0; i < p.blocks.size(); ++i) {
        blk.reset();
        blk.bind(1, run_id).bind(2, static_cast<std::int64_t>(i)).bind(3, block_json(i, p.blocks[i]).dump());
        blk.bind(4, p.blocks[i].flags.empty() ? 0 : 1).run();
        flagged = flagged || !p.blocks[i].flags.empty();
    }
    write_series(c, run_id, SeriesId::Forces, force_series(p));
    write_series(c, run_id, SeriesId::Motion, motion_series(motion));
    c.prepare("INSERT INTO run_stock(run_id, data) VALUES (?, ?)")
        .bind(1, run_id)
        .bind_blob(2, stock_bytes.data(), stock_bytes.size())
        .run();
    const int alerts = raise_alerts(c, run_id, p, limit_alerts);
    json summary = summary_json(p, p.final_stock ? force_model::stock_volume_mm3(*p.final_stock) : 0.0);
    summary["alerts"] = alerts;
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
        write_series(c, run_id, SeriesId::CommandedForces, cmd_series);
        const json commanded_summary = summary_json(cmd, cmd.final_stock ? force_model::stock_volume_mm3(*cmd.final_stock) : 0.0);
        c.prepare("INSERT INTO run_program(run_id, body) VALUES (?, ?)")
            .bind(1, run_id)
            .bind(2, program_body(*program, commanded_summary).dump())
            .run();
        const auto& q = program->run.mapping.quality;
        summary["program"] = {{"program_blocks", program->run.program.blocks.size()},
                              {"mapped", program->run.mapped},
                              {"matched_fraction", q.matched_fraction},
                              {"commanded_peak_force_N", commanded_summary["peak_force_N"]},
                              {"commanded_simulated_s", cmd.stats.simulated_s}};
    }
    c.prepare(
         "UPDATE runs SET state = 'done', progress = 1, summary = ?, block_names = ?, flagged = ?, finished_at = ? "
         "WHERE id = ?")
        .bind(1, summary.dump())
        .bind(2, json(names).dump())
        .bind(3, (flagged || alerts > 0) ? 1 : 0)
        .bind(4, db::now_iso())
        .bind(5, run_id)
        .run();
    tx.commit();
    return alerts;
}

}  // namespace cutload::server
