// PostgreSQL: live runs.
#include "postgres/store.hpp"

namespace cutload::db::postgres {

std::int64_t LiveRuns::create(const NewRun& run, const std::string& source_json) {
    // Running from the start: a worker claims only queued runs, so none ever takes a live one.
    // Run and live record in one statement, so neither exists without the other.
    return c_
        .run("WITH run AS (INSERT INTO runs(name, program, machine_id, tool_id, material_id, base_run, state, attempts, "
             "upload_dir, inputs, created_at, started_at) VALUES ($1,$2,$3,$4,$5,$6,$7,1,'',$8,$9,$9) RETURNING id), "
             "live AS (INSERT INTO live_runs(run_id, source, updated_at) SELECT id, $10, $9 FROM run) "
             "SELECT id FROM run",
             Params()
                 .add(run.name)
                 .add(run.program)
                 .add(run.machine_id)
                 .add(run.tool_id)
                 .add(run.material_id)
                 .add(run.base_run)
                 .add(to_text(JobState::Running))
                 .add(run.inputs_json)
                 .add(run.created_at)
                 .add(source_json))
        .i64(0, 0);
}

std::optional<LiveRecord> LiveRuns::get(std::int64_t run_id) {
    auto r = c_.run("SELECT run_id, source, open, connection, lag_ms, machine_t_s, rows, gaps, end_reason, updated_at, "
                    "block_names, alerts FROM live_runs WHERE run_id = $1",
                    Params().add(run_id));
    if (r.empty()) return std::nullopt;
    LiveRecord o;
    o.run_id = r.i64(0, 0);
    o.source_json = r.text(0, 1);
    o.open = r.boolean(0, 2);
    o.connection = r.text(0, 3);
    o.lag_ms = r.real(0, 4);
    o.machine_t_s = r.real(0, 5);
    o.rows = r.i64(0, 6);
    o.gaps_json = r.text(0, 7);
    o.end_reason = r.opt_text(0, 8);
    o.updated_at = r.text(0, 9);
    o.block_names_json = r.text(0, 10);
    o.alerts = r.i64(0, 11);
    return o;
}

std::vector<std::int64_t> LiveRuns::open_runs() {
    auto r = c_.run("SELECT run_id FROM live_runs WHERE open ORDER BY run_id");
    std::vector<std::int64_t> out;
    for (int i = 0; i < r.rows(); ++i) out.push_back(r.i64(i, 0));
    return out;
}

void LiveRuns::update_status(std::int64_t run_id, const LiveStatusUpdate& u) {
    c_.run("UPDATE live_runs SET connection = $1, lag_ms = $2, machine_t_s = $3, rows = $4, gaps = $5, updated_at = $6, "
           "block_names = $7, alerts = $8 WHERE run_id = $9 AND open",
           Params()
               .add(u.connection)
               .add(u.lag_ms)
               .add(u.machine_t_s)
               .add(u.rows)
               .add(u.gaps_json)
               .add(u.updated_at)
               .add(u.block_names_json)
               .add(u.alerts)
               .add(run_id));
}

std::int64_t LiveRuns::add_chunk(std::int64_t run_id, double t0_s, double t1_s, std::int64_t n,
                                 std::span<const unsigned char> data) {
    // The next sequence number and the insert in one statement (one writer per live run).
    return c_
        .run("INSERT INTO live_chunks(run_id, seq, t0_s, t1_s, n, data) "
             "SELECT $1, COALESCE(MAX(seq), 0) + 1, $2, $3, $4, $5 FROM live_chunks WHERE run_id = $1 RETURNING seq",
             Params().add(run_id).add(t0_s).add(t1_s).add(n).add_blob(data))
        .i64(0, 0);
}

std::vector<LiveChunk> LiveRuns::chunks(std::int64_t run_id, std::int64_t after_seq, std::int64_t limit) {
    auto r = c_.run("SELECT seq, t0_s, t1_s, n, data FROM live_chunks WHERE run_id = $1 AND seq > $2 ORDER BY seq LIMIT $3",
                    Params().add(run_id).add(after_seq).add(limit));
    std::vector<LiveChunk> out;
    for (int i = 0; i < r.rows(); ++i) {
        LiveChunk c;
        c.seq = r.i64(i, 0);
        c.t0_s = r.real(i, 1);
        c.t1_s = r.real(i, 2);
        c.n = r.i64(i, 3);
        const auto b = r.blob(i, 4);
        c.data.assign(b.begin(), b.end());
        out.push_back(std::move(c));
    }
    return out;
}

void LiveRuns::add_block(std::int64_t run_id, std::int64_t idx, const std::string& body_json, bool flagged) {
    c_.run("INSERT INTO live_blocks(run_id, idx, body, flagged) VALUES ($1,$2,$3,$4)",
           Params().add(run_id).add(idx).add(body_json).add(flagged));
}

std::vector<BlockRow> LiveRuns::blocks(std::int64_t run_id, std::int64_t from_idx) {
    auto r = c_.run("SELECT idx, body FROM live_blocks WHERE run_id = $1 AND idx >= $2 ORDER BY idx",
                    Params().add(run_id).add(from_idx));
    std::vector<BlockRow> out;
    for (int i = 0; i < r.rows(); ++i) out.push_back(BlockRow{r.i64(i, 0), r.text(i, 1)});
    return out;
}

void LiveRuns::close(std::int64_t run_id, const std::string& end_reason, const std::string& now) {
    c_.run("UPDATE live_runs SET open = FALSE, connection = 'closed', end_reason = $1, updated_at = $2 WHERE run_id = $3",
           Params().add(end_reason).add(now).add(run_id));
    c_.run("DELETE FROM live_chunks WHERE run_id = $1", Params().add(run_id));
    c_.run("DELETE FROM live_blocks WHERE run_id = $1", Params().add(run_id));
}

}  // namespace cutload::db::postgres
