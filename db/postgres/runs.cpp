// PostgreSQL: runs and their results (run_blocks, series_chunks, run_stock, run_program).
#include "postgres/store.hpp"

#include <fmt/format.h>

#include <ostream>
#include <streambuf>

namespace cutload::db::postgres {
namespace {

// std::streambuf appending to a string (reserved by the caller).
class StringSink : public std::streambuf {
public:
    explicit StringSink(std::string& s) : s_(s) {}

protected:
    int_type overflow(int_type c) override {
        if (!traits_type::eq_int_type(c, traits_type::eof())) s_.push_back(traits_type::to_char_type(c));
        return traits_type::not_eof(c);
    }
    std::streamsize xsputn(const char* p, std::streamsize n) override {
        s_.append(p, static_cast<std::size_t>(n));
        return n;
    }

private:
    std::string& s_;
};

constexpr const char* kRunColumns =
    "id, name, program, machine_id, tool_id, material_id, base_run, state, progress, error, attempts, upload_dir, "
    "inputs, summary, flagged, created_at, started_at, finished_at";

RunRecord run_row(const Result& r, int i) {
    RunRecord o;
    o.id = r.i64(i, 0);
    o.name = r.opt_text(i, 1);
    o.program = r.opt_text(i, 2);
    o.machine_id = r.opt_i64(i, 3);
    o.tool_id = r.opt_i64(i, 4);
    o.material_id = r.opt_i64(i, 5);
    o.base_run = r.opt_i64(i, 6);
    o.state = job_state_from_text(r.text(i, 7));
    o.progress = r.real(i, 8);
    o.error = r.opt_text(i, 9);
    o.attempts = r.i64(i, 10);
    o.upload_dir = r.text(i, 11);
    o.inputs_json = r.text(i, 12);
    o.summary_json = r.opt_text(i, 13);
    o.flagged = r.boolean(i, 14);
    o.created_at = r.text(i, 15);
    o.started_at = r.opt_text(i, 16);
    o.finished_at = r.opt_text(i, 17);
    return o;
}

}  // namespace

std::int64_t Runs::create(const NewRun& run) {
    notify_job_queued(c_);
    return c_
        .run("INSERT INTO runs(name, program, machine_id, tool_id, material_id, base_run, state, upload_dir, inputs, created_at) "
             "VALUES ($1,$2,$3,$4,$5,$6,$7,'',$8,$9) RETURNING id",
             Params()
                 .add(run.name)
                 .add(run.program)
                 .add(run.machine_id)
                 .add(run.tool_id)
                 .add(run.material_id)
                 .add(run.base_run)
                 .add(to_text(JobState::Queued))
                 .add(run.inputs_json)
                 .add(run.created_at))
        .i64(0, 0);
}

void Runs::set_upload_dir(std::int64_t id, const std::string& upload_dir) {
    c_.run("UPDATE runs SET upload_dir = $1 WHERE id = $2", Params().add(upload_dir).add(id));
}

std::optional<RunRecord> Runs::get(std::int64_t id) {
    auto r = c_.run(fmt::format("SELECT {} FROM runs WHERE id = $1", kRunColumns), Params().add(id));
    if (r.empty()) return std::nullopt;
    return run_row(r, 0);
}

std::optional<RunStatus> Runs::status(std::int64_t id) {
    // Inside a transaction (storing a run's results after checking it is still running) the row
    // stays locked until the transaction ends: a cancel from another process waits and then finds
    // the run done, as SQLite's single writer makes it. Outside one, a plain read (no row lock
    // for the result queries that ask it).
    auto r = c_.in_transaction()
                 ? c_.run("SELECT state, finished_at, upload_dir FROM runs WHERE id = $1 FOR NO KEY UPDATE", Params().add(id))
                 : c_.run("SELECT state, finished_at, upload_dir FROM runs WHERE id = $1", Params().add(id));
    if (r.empty()) return std::nullopt;
    return RunStatus{job_state_from_text(r.text(0, 0)), r.opt_text(0, 1), r.text(0, 2)};
}

std::vector<RunRecord> Runs::list(const RunFilter& f) {
    const std::optional<std::string> state = f.state ? std::optional<std::string>(to_text(*f.state)) : std::nullopt;
    auto r = c_.run(fmt::format("SELECT {} FROM runs WHERE ($1::bigint IS NULL OR id < $1) AND ($2::bigint IS NULL OR machine_id = $2) "
                                "AND ($3::text IS NULL OR program = $3) AND ($4::text IS NULL OR state = $4) "
                                "AND ($5::boolean IS NULL OR flagged = $5) AND ($6::text IS NULL OR created_at >= $6) "
                                "AND ($7::text IS NULL OR created_at <= $7) ORDER BY id DESC LIMIT $8",
                                kRunColumns),
                    Params()
                        .add(f.before_id)
                        .add(f.machine_id)
                        .add(f.program)
                        .add(state)
                        .add(f.flagged)
                        .add(f.created_since)
                        .add(f.created_until)
                        .add(f.limit));
    std::vector<RunRecord> out;
    for (int i = 0; i < r.rows(); ++i) out.push_back(run_row(r, i));
    return out;
}

bool Runs::remove(std::int64_t id) { return c_.run("DELETE FROM runs WHERE id = $1", Params().add(id)).affected() > 0; }

bool Runs::upload_dir_in_use(const std::string& upload_dir) {
    return !c_.run("SELECT 1 FROM runs WHERE upload_dir = $1 LIMIT 1", Params().add(upload_dir)).empty();
}

void Runs::add_block(std::int64_t run_id, std::int64_t idx, const std::string& body_json, bool flagged) {
    c_.run("INSERT INTO run_blocks(run_id, idx, body, flagged) VALUES ($1,$2,$3,$4)",
           Params().add(run_id).add(idx).add(body_json).add(flagged));
}

void Runs::add_series_chunk(std::int64_t run_id, const SeriesChunkInfo& i, std::span<const unsigned char> data) {
    c_.run("INSERT INTO series_chunks(run_id, series, level, chunk, t0_s, t1_s, n, data) VALUES ($1,$2,$3,$4,$5,$6,$7,$8)",
           Params().add(run_id).add(i.series).add(i.level).add(i.chunk).add(i.t0_s).add(i.t1_s).add(i.n).add_blob(data));
}

void Runs::set_final_stock(std::int64_t run_id, std::uint64_t bytes, const std::function<void(std::ostream&)>& write) {
    // A bytea parameter is one value in memory: the bytes are gathered first.
    std::string data;
    data.reserve(bytes);
    {
        StringSink sink(data);
        std::ostream out(&sink);
        write(out);
        out.flush();
    }
    if (data.size() != bytes)
        throw std::runtime_error(fmt::format("postgres: the final stock of run {}: {} of {} bytes came", run_id, data.size(),
                                             bytes));
    c_.run("INSERT INTO run_stock(run_id, data) VALUES ($1, $2)", Params().add(run_id).add_blob(data));
}

void Runs::set_program_body(std::int64_t run_id, const std::string& body_json) {
    c_.run("INSERT INTO run_program(run_id, body) VALUES ($1, $2)", Params().add(run_id).add(body_json));
}

void Runs::mark_done(std::int64_t run_id, const std::string& summary_json, const std::string& block_names_json,
                     bool flagged, const std::string& finished_at) {
    c_.run("UPDATE runs SET state = $1, progress = 1, summary = $2, block_names = $3, flagged = $4, finished_at = $5 "
           "WHERE id = $6",
           Params().add(to_text(JobState::Done)).add(summary_json).add(block_names_json).add(flagged).add(finished_at).add(run_id));
}

std::vector<BlockRow> Runs::blocks(std::int64_t run_id, std::int64_t from_idx, std::optional<bool> flagged,
                                   std::int64_t limit) {
    auto r = c_.run("SELECT idx, body FROM run_blocks WHERE run_id = $1 AND idx >= $2 AND ($3::boolean IS NULL OR flagged = $3) "
                    "ORDER BY idx LIMIT $4",
                    Params().add(run_id).add(from_idx).add(flagged).add(limit));
    std::vector<BlockRow> out;
    out.reserve(static_cast<std::size_t>(r.rows()));
    for (int i = 0; i < r.rows(); ++i) out.push_back(BlockRow{r.i64(i, 0), r.text(i, 1)});
    return out;
}

std::vector<SeriesChunkInfo> Runs::series_index(std::int64_t run_id, int series) {
    auto r = c_.run("SELECT level, chunk, t0_s, t1_s, n FROM series_chunks WHERE run_id = $1 AND series = $2 "
                    "ORDER BY level, chunk",
                    Params().add(run_id).add(series));
    std::vector<SeriesChunkInfo> out;
    out.reserve(static_cast<std::size_t>(r.rows()));
    for (int i = 0; i < r.rows(); ++i)
        out.push_back(SeriesChunkInfo{series, static_cast<int>(r.i64(i, 0)), r.i64(i, 1), r.real(i, 2), r.real(i, 3), r.i64(i, 4)});
    return out;
}

bool Runs::read_series_chunk(std::int64_t run_id, int series, int level, std::int64_t chunk,
                             const std::function<void(std::int64_t, std::span<const unsigned char>)>& use) {
    auto r = c_.run("SELECT n, data FROM series_chunks WHERE run_id = $1 AND series = $2 AND level = $3 AND chunk = $4",
                    Params().add(run_id).add(series).add(level).add(chunk));
    if (r.empty()) return false;
    use(r.i64(0, 0), r.blob(0, 1));
    return true;
}

bool Runs::has_final_stock(std::int64_t run_id) {
    return !c_.run("SELECT 1 FROM run_stock WHERE run_id = $1", Params().add(run_id)).empty();
}

bool Runs::read_final_stock(std::int64_t run_id, const std::function<void(std::span<const unsigned char>)>& use) {
    auto r = c_.run("SELECT data FROM run_stock WHERE run_id = $1", Params().add(run_id));
    if (r.empty()) return false;
    use(r.blob(0, 0));
    return true;
}

std::optional<std::string> Runs::program_body(std::int64_t run_id) {
    auto r = c_.run("SELECT body FROM run_program WHERE run_id = $1", Params().add(run_id));
    if (r.empty()) return std::nullopt;
    return r.text(0, 0);
}

std::optional<std::string> Runs::block_names(std::int64_t run_id) {
    auto r = c_.run("SELECT block_names FROM runs WHERE id = $1", Params().add(run_id));
    if (r.empty()) return std::nullopt;
    return r.opt_text(0, 0);
}

}  // namespace cutload::db::postgres
