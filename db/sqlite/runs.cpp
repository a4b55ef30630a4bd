// SQLite: runs and their results (run_blocks, series_chunks, run_stock, run_program).
#include "sqlite/store.hpp"

#include <fmt/format.h>

namespace cutload::db::sqlite {
namespace {

constexpr const char* kRunColumns =
    "id, name, program, machine_id, tool_id, material_id, base_run, state, progress, error, attempts, upload_dir, "
    "inputs, summary, flagged, created_at, started_at, finished_at";

RunRecord run_row(const Stmt& st) {
    RunRecord r;
    r.id = st.i64(0);
    r.name = st.opt_text(1);
    r.program = st.opt_text(2);
    r.machine_id = st.opt_i64(3);
    r.tool_id = st.opt_i64(4);
    r.material_id = st.opt_i64(5);
    r.base_run = st.opt_i64(6);
    r.state = job_state_from_text(st.text(7));
    r.progress = st.real(8);
    r.error = st.opt_text(9);
    r.attempts = st.i64(10);
    r.upload_dir = st.text(11);
    r.inputs_json = st.text(12);
    r.summary_json = st.opt_text(13);
    r.flagged = st.i64(14) != 0;
    r.created_at = st.text(15);
    r.started_at = st.opt_text(16);
    r.finished_at = st.opt_text(17);
    return r;
}

}  // namespace

std::int64_t Runs::create(const NewRun& run) {
    auto st = c_.prepare(
        "INSERT INTO runs(name, program, machine_id, tool_id, material_id, base_run, state, upload_dir, inputs, created_at) "
        "VALUES (?,?,?,?,?,?,?,'',?,?)");
    st.bind(1, run.name).bind(2, run.program).bind(3, run.machine_id).bind(4, run.tool_id).bind(5, run.material_id);
    st.bind(6, run.base_run).bind(7, to_text(JobState::Queued)).bind(8, run.inputs_json).bind(9, run.created_at).run();
    return c_.last_insert_id();
}

void Runs::set_upload_dir(std::int64_t id, const std::string& upload_dir) {
    c_.prepare("UPDATE runs SET upload_dir = ? WHERE id = ?").bind(1, upload_dir).bind(2, id).run();
}

std::optional<RunRecord> Runs::get(std::int64_t id) {
    auto st = c_.prepare(fmt::format("SELECT {} FROM runs WHERE id = ?", kRunColumns));
    st.bind(1, id);
    if (!st.step()) return std::nullopt;
    return run_row(st);
}

std::optional<RunStatus> Runs::status(std::int64_t id) {
    auto st = c_.prepare("SELECT state, finished_at, upload_dir FROM runs WHERE id = ?");
    st.bind(1, id);
    if (!st.step()) return std::nullopt;
    return RunStatus{job_state_from_text(st.text(0)), st.opt_text(1), st.text(2)};
}

std::vector<RunRecord> Runs::list(const RunFilter& f) {
    auto st = c_.prepare(fmt::format(
        "SELECT {} FROM runs WHERE (?1 IS NULL OR id < ?1) AND (?2 IS NULL OR machine_id = ?2) "
        "AND (?3 IS NULL OR program = ?3) AND (?4 IS NULL OR state = ?4) AND (?5 IS NULL OR flagged = ?5) "
        "AND (?6 IS NULL OR created_at >= ?6) AND (?7 IS NULL OR created_at <= ?7) ORDER BY id DESC LIMIT ?8",
        kRunColumns));
    st.bind(1, f.before_id).bind(2, f.machine_id).bind(3, f.program);
    if (f.state)
        st.bind(4, to_text(*f.state));
    else
        st.bind_null(4);
    st.bind(5, f.flagged).bind(6, f.created_since).bind(7, f.created_until).bind(8, f.limit);
    std::vector<RunRecord> out;
    while (st.step()) out.push_back(run_row(st));
    return out;
}

bool Runs::remove(std::int64_t id) {
    c_.prepare("DELETE FROM runs WHERE id = ?").bind(1, id).run();
    return c_.changes() > 0;
}

bool Runs::upload_dir_in_use(const std::string& upload_dir) {
    auto st = c_.prepare("SELECT 1 FROM runs WHERE upload_dir = ?");
    st.bind(1, upload_dir);
    return st.step();
}

void Runs::add_block(std::int64_t run_id, std::int64_t idx, const std::string& body_json, bool flagged) {
    c_.prepare("INSERT INTO run_blocks(run_id, idx, body, flagged) VALUES (?,?,?,?)")
        .bind(1, run_id)
        .bind(2, idx)
        .bind(3, body_json)
        .bind(4, flagged)
        .run();
}

void Runs::add_series_chunk(std::int64_t run_id, const SeriesChunkInfo& i, std::span<const unsigned char> data) {
    auto st = c_.prepare(
        "INSERT INTO series_chunks(run_id, series, level, chunk, t0_s, t1_s, n, data) VALUES (?,?,?,?,?,?,?,?)");
    st.bind(1, run_id).bind(2, i.series).bind(3, i.level).bind(4, i.chunk);
    st.bind(5, i.t0_s).bind(6, i.t1_s).bind(7, i.n).bind_blob(8, data.data(), data.size());
    st.run();
}

void Runs::set_final_stock(std::int64_t run_id, std::uint64_t bytes, const std::function<void(std::ostream&)>& write) {
    // run_id is the table's rowid (INTEGER PRIMARY KEY).
    c_.prepare("INSERT INTO run_stock(run_id, data) VALUES (?, zeroblob(?))")
        .bind(1, run_id)
        .bind(2, static_cast<std::int64_t>(bytes))
        .run();
    c_.write_blob("run_stock", "data", run_id, bytes, write);
}

void Runs::set_program_body(std::int64_t run_id, const std::string& body_json) {
    c_.prepare("INSERT INTO run_program(run_id, body) VALUES (?, ?)").bind(1, run_id).bind(2, body_json).run();
}

void Runs::mark_done(std::int64_t run_id, const std::string& summary_json, const std::string& block_names_json,
                     bool flagged, const std::string& finished_at) {
    c_.prepare(
          "UPDATE runs SET state = ?, progress = 1, summary = ?, block_names = ?, flagged = ?, finished_at = ? WHERE id = ?")
        .bind(1, to_text(JobState::Done))
        .bind(2, summary_json)
        .bind(3, block_names_json)
        .bind(4, flagged)
        .bind(5, finished_at)
        .bind(6, run_id)
        .run();
}

std::vector<BlockRow> Runs::blocks(std::int64_t run_id, std::int64_t from_idx, std::optional<bool> flagged,
                                   std::int64_t limit) {
    auto st = c_.prepare(
        "SELECT idx, body FROM run_blocks WHERE run_id = ?1 AND idx >= ?2 AND (?3 IS NULL OR flagged = ?3) "
        "ORDER BY idx LIMIT ?4");
    st.bind(1, run_id).bind(2, from_idx).bind(3, flagged).bind(4, limit);
    std::vector<BlockRow> out;
    while (st.step()) out.push_back(BlockRow{st.i64(0), st.text(1)});
    return out;
}

std::vector<SeriesChunkInfo> Runs::series_index(std::int64_t run_id, int series) {
    auto st = c_.prepare(
        "SELECT level, chunk, t0_s, t1_s, n FROM series_chunks WHERE run_id = ? AND series = ? ORDER BY level, chunk");
    st.bind(1, run_id).bind(2, series);
    std::vector<SeriesChunkInfo> out;
    while (st.step())
        out.push_back(SeriesChunkInfo{series, static_cast<int>(st.i64(0)), st.i64(1), st.real(2), st.real(3), st.i64(4)});
    return out;
}

bool Runs::read_series_chunk(std::int64_t run_id, int series, int level, std::int64_t chunk,
                             const std::function<void(std::int64_t, std::span<const unsigned char>)>& use) {
    auto st = c_.prepare("SELECT n, data FROM series_chunks WHERE run_id = ? AND series = ? AND level = ? AND chunk = ?");
    st.bind(1, run_id).bind(2, series).bind(3, level).bind(4, chunk);
    if (!st.step()) return false;
    use(st.i64(0), st.blob(1));
    return true;
}

bool Runs::has_final_stock(std::int64_t run_id) {
    auto st = c_.prepare("SELECT 1 FROM run_stock WHERE run_id = ?");
    st.bind(1, run_id);
    return st.step();
}

bool Runs::read_final_stock(std::int64_t run_id, const std::function<void(std::span<const unsigned char>)>& use) {
    auto st = c_.prepare("SELECT data FROM run_stock WHERE run_id = ?");
    st.bind(1, run_id);
    if (!st.step()) return false;
    use(st.blob(0));
    return true;
}

std::optional<std::string> Runs::program_body(std::int64_t run_id) {
    auto st = c_.prepare("SELECT body FROM run_program WHERE run_id = ?");
    st.bind(1, run_id);
    if (!st.step()) return std::nullopt;
    return st.text(0);
}

std::optional<std::string> Runs::block_names(std::int64_t run_id) {
    auto st = c_.prepare("SELECT block_names FROM runs WHERE id = ?");
    st.bind(1, run_id);
    if (!st.step()) return std::nullopt;
    return st.opt_text(0);
}

}  // namespace cutload::db::sqlite
