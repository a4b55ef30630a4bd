// SQLite: live runs.
#include "sqlite/store.hpp"

namespace cutload::db::sqlite {

std::int64_t LiveRuns::create(const NewRun& run, const std::string& source_json) {
    // Running from the start: a worker claims only queued runs, so none ever takes a live one.
    c_.prepare("INSERT INTO runs(name, program, machine_id, tool_id, material_id, base_run, state, attempts, upload_dir, "
               "inputs, created_at, started_at) VALUES (?,?,?,?,?,?,?,1,'',?,?,?)")
        .bind(1, run.name)
        .bind(2, run.program)
        .bind(3, run.machine_id)
        .bind(4, run.tool_id)
        .bind(5, run.material_id)
        .bind(6, run.base_run)
        .bind(7, to_text(JobState::Running))
        .bind(8, run.inputs_json)
        .bind(9, run.created_at)
        .bind(10, run.created_at)
        .run();
    const std::int64_t id = c_.last_insert_id();
    c_.prepare("INSERT INTO live_runs(run_id, source, updated_at) VALUES (?,?,?)")
        .bind(1, id)
        .bind(2, source_json)
        .bind(3, run.created_at)
        .run();
    return id;
}

std::optional<LiveRecord> LiveRuns::get(std::int64_t run_id) {
    auto st = c_.prepare("SELECT run_id, source, open, connection, lag_ms, machine_t_s, rows, gaps, end_reason, updated_at, "
                         "block_names, alerts FROM live_runs WHERE run_id = ?");
    st.bind(1, run_id);
    if (!st.step()) return std::nullopt;
    LiveRecord r;
    r.run_id = st.i64(0);
    r.source_json = st.text(1);
    r.open = st.i64(2) != 0;
    r.connection = st.text(3);
    r.lag_ms = st.real(4);
    r.machine_t_s = st.real(5);
    r.rows = st.i64(6);
    r.gaps_json = st.text(7);
    r.end_reason = st.opt_text(8);
    r.updated_at = st.text(9);
    r.block_names_json = st.text(10);
    r.alerts = st.i64(11);
    return r;
}

std::vector<std::int64_t> LiveRuns::open_runs() {
    auto st = c_.prepare("SELECT run_id FROM live_runs WHERE open = 1 ORDER BY run_id");
    std::vector<std::int64_t> out;
    while (st.step()) out.push_back(st.i64(0));
    return out;
}

void LiveRuns::update_status(std::int64_t run_id, const LiveStatusUpdate& u) {
    c_.prepare("UPDATE live_runs SET connection = ?, lag_ms = ?, machine_t_s = ?, rows = ?, gaps = ?, updated_at = ?, "
               "block_names = ?, alerts = ? WHERE run_id = ? AND open = 1")
        .bind(1, u.connection)
        .bind(2, u.lag_ms)
        .bind(3, u.machine_t_s)
        .bind(4, u.rows)
        .bind(5, u.gaps_json)
        .bind(6, u.updated_at)
        .bind(7, u.block_names_json)
        .bind(8, u.alerts)
        .bind(9, run_id)
        .run();
}

std::int64_t LiveRuns::add_chunk(std::int64_t run_id, double t0_s, double t1_s, std::int64_t n,
                                 std::span<const unsigned char> data) {
    auto st = c_.prepare("SELECT COALESCE(MAX(seq), 0) + 1 FROM live_chunks WHERE run_id = ?");
    st.bind(1, run_id);
    st.step();
    const std::int64_t seq = st.i64(0);
    st.reset();
    c_.prepare("INSERT INTO live_chunks(run_id, seq, t0_s, t1_s, n, data) VALUES (?,?,?,?,?,?)")
        .bind(1, run_id)
        .bind(2, seq)
        .bind(3, t0_s)
        .bind(4, t1_s)
        .bind(5, n)
        .bind_blob(6, data.data(), data.size())
        .run();
    return seq;
}

std::vector<LiveChunk> LiveRuns::chunks(std::int64_t run_id, std::int64_t after_seq, std::int64_t limit) {
    auto st = c_.prepare("SELECT seq, t0_s, t1_s, n, data FROM live_chunks WHERE run_id = ? AND seq > ? ORDER BY seq LIMIT ?");
    st.bind(1, run_id).bind(2, after_seq).bind(3, limit);
    std::vector<LiveChunk> out;
    while (st.step()) {
        LiveChunk c;
        c.seq = st.i64(0);
        c.t0_s = st.real(1);
        c.t1_s = st.real(2);
        c.n = st.i64(3);
        const auto b = st.blob(4);
        c.data.assign(b.begin(), b.end());
        out.push_back(std::move(c));
    }
    return out;
}

void LiveRuns::add_block(std::int64_t run_id, std::int64_t idx, const std::string& body_json, bool flagged) {
    c_.prepare("INSERT INTO live_blocks(run_id, idx, body, flagged) VALUES (?,?,?,?)")
        .bind(1, run_id)
        .bind(2, idx)
        .bind(3, body_json)
        .bind(4, flagged)
        .run();
}

std::vector<BlockRow> LiveRuns::blocks(std::int64_t run_id, std::int64_t from_idx) {
    auto st = c_.prepare("SELECT idx, body FROM live_blocks WHERE run_id = ? AND idx >= ? ORDER BY idx");
    st.bind(1, run_id).bind(2, from_idx);
    std::vector<BlockRow> out;
    while (st.step()) out.push_back(BlockRow{st.i64(0), st.text(1)});
    return out;
}

void LiveRuns::close(std::int64_t run_id, const std::string& end_reason, const std::string& now) {
    c_.prepare("UPDATE live_runs SET open = 0, connection = 'closed', end_reason = ?, updated_at = ? WHERE run_id = ?")
        .bind(1, end_reason)
        .bind(2, now)
        .bind(3, run_id)
        .run();
    c_.prepare("DELETE FROM live_chunks WHERE run_id = ?").bind(1, run_id).run();
    c_.prepare("DELETE FROM live_blocks WHERE run_id = ?").bind(1, run_id).run();
}

}  // namespace cutload::db::sqlite
