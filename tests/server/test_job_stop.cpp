// Jobs that stop and storage that shrinks (issue 19): a cancel or a DELETE stops a running run
// (no 409), deleting runs gives their space back and empties the WAL, and what the server creates
// is readable by its owner only. The sizes and latencies are printed: they are figures, not bounds.
#include "db/jobs.hpp"
#include "db/runs.hpp"
#include "db/store.hpp"
#include "harness.hpp"
#include "force_model/force_model.hpp"
#include "server/results.hpp"

#include <sys/stat.h>

#include <algorithm>
#include <atomic>
#include <span>
#include <string>

using namespace cutload::test;

namespace {

// A run that computes for seconds on one core: a fine angle step over a 4 s slot.
json slow_spec() {
    json s = slot_spec();
    s["resolution"] = {{"angle_step_deg", 0.5}, {"axial_step_mm", 0.1}, {"grid_mm", 0.1}};
    return s;
}

json get_run(httplib::Client& c, std::int64_t id) { return body(c.Get(("/api/v1/runs/" + std::to_string(id)).c_str())); }

// Waits until the run computes forces (progress above 0), so a stop lands mid-prediction.
void wait_computing(httplib::Client& c, std::int64_t id) {
    for (int i = 0; i < 2000; ++i) {
        const json run = get_run(c, id);
        if (run["state"] == "running" && run["progress"].get<double>() > 0) return;
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    FAIL("run " << id << " never started computing");
}

std::int64_t size_of(const fs::path& p) {
    std::error_code ec;
    const auto n = fs::file_size(p, ec);
    return ec ? 0 : static_cast<std::int64_t>(n);
}

unsigned mode_of(const fs::path& p) {
    struct stat st {};
    REQUIRE(::stat(p.c_str(), &st) == 0);
    return st.st_mode & 0777u;
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

TEST_CASE("job stop: cancel and DELETE stop a run mid-prediction, DELETE answers 204 (not 409) and leaves nothing") {
    TestServer ts;
    auto c = ts.admin();
    const std::int64_t cancelled = body(upload(c, slot_log_csv(4.0), slow_spec()))["id"];
    wait_computing(c, cancelled);
    auto t0 = std::chrono::steady_clock::now();
    REQUIRE(c.Post(("/api/v1/runs/" + std::to_string(cancelled) + "/cancel").c_str())->status == 202);
    const json run = wait_finished(c, cancelled, 30);
    const double cancel_s = seconds_since(t0);
    REQUIRE(run["state"] == "cancelled");
    REQUIRE(body(c.Get(("/api/v1/runs/" + std::to_string(cancelled) + "/blocks").c_str())).value("items", json::array()).empty());

    const std::size_t files_before = files_under(ts.data_dir());
    const std::int64_t deleted = body(upload(c, slot_log_csv(4.0), slow_spec()))["id"];
    wait_computing(c, deleted);
    t0 = std::chrono::steady_clock::now();
    const auto del = c.Delete(("/api/v1/runs/" + std::to_string(deleted)).c_str());
    const double delete_s = seconds_since(t0);
    REQUIRE(del);
    INFO(del->body);
    REQUIRE(del->status == 204);
    require_error(c.Get(("/api/v1/runs/" + std::to_string(deleted)).c_str()), 404, "not_found");
    // Nothing of the deleted run is left, and the worker let go: the next run is computed.
    REQUIRE(files_under(ts.data_dir()) == files_before);
    const std::int64_t next = body(upload(c, slot_log_csv(0.3), slot_spec()))["id"];
    REQUIRE(wait_finished(c, next, 30)["state"] == "done");
    WARN("cancel mid-prediction: state cancelled " << cancel_s * 1000 << " ms after POST cancel; DELETE of a running run "
                                                     "answered 204 in "
                                                  << delete_s * 1000 << " ms");
}

TEST_CASE("job stop: DELETE of 10 runs shrinks the database file, the WAL stays under its bound, files are owner-only") {
    CUTLOAD_SQLITE_ONLY("the database file, its WAL and their modes are SQLite's (PostgreSQL's files are its server's)");
    TestServer ts;
    auto c = ts.admin();
    std::vector<std::int64_t> ids;
    json spec = slot_spec();
    spec["resolution"] = {{"angle_step_deg", 1}, {"axial_step_mm", 0.1}, {"grid_mm", 0.1}};
    for (int i = 0; i < 10; ++i) ids.push_back(body(upload(c, slot_log_csv(1.0 + 0.05 * i), spec))["id"]);
    for (const auto id : ids) REQUIRE(wait_finished(c, id, 120)["state"] == "done");

    const fs::path db = ts.opt.db_path;
    const fs::path wal = ts.opt.db_path + "-wal";
    const std::int64_t db_full = size_of(db), wal_full = size_of(wal);
    // Owner-only (the default umask 077): the database, its WAL and the uploads.
    REQUIRE(mode_of(db) == 0600u);
    if (fs::exists(wal)) REQUIRE(mode_of(wal) == 0600u);
    for (const auto& e : fs::recursive_directory_iterator(ts.data_dir())) {
        INFO(e.path().string());
        REQUIRE(mode_of(e.path()) == (e.is_directory() ? 0700u : 0600u));
    }

    std::int64_t wal_max = wal_full;
    for (const auto id : ids) {
        REQUIRE(c.Delete(("/api/v1/runs/" + std::to_string(id)).c_str())->status == 204);
        wal_max = std::max(wal_max, size_of(wal));
    }
    const std::int64_t db_empty = size_of(db), wal_empty = size_of(wal);
    WARN("10 runs: database " << db_full << " B, WAL " << wal_full << " B; after deleting them: database " << db_empty
                              << " B, WAL " << wal_empty << " B (largest WAL seen " << wal_max << " B)");
    // The runs' rows were most of the file: at least half of it comes back.
    REQUIRE(db_empty < db_full / 2);
    // The documented bound (docs/api.md, "Disk"): 64 MiB after a checkpoint; emptied by a DELETE.
    REQUIRE(wal_max <= (64 << 20) + (4 << 20));
    REQUIRE(wal_empty == 0);
}

TEST_CASE("job stop: a cancel that lands while a run's results are written rolls them back, without one they commit") {
    TempDir dir;
    const std::string path = store_location(dir.path(), "store.db");
    auto store = cutload::db::Store::open(path);
    store->migrate();
    auto s = store->session();
    const auto claimed = [&] {
        cutload::db::NewRun nr;
        nr.inputs_json = "{}";
        nr.created_at = cutload::db::now_iso();
        const std::int64_t id = s->runs().create(nr);
        REQUIRE(s->jobs().claim_oldest(cutload::db::kRunQueue, cutload::db::now_iso(), {"test/1", "9999-12-31T00:00:00.000Z"}) == id);
        return id;
    };
    // Two samples and one block: enough for every table store_result writes.
    cutload::motion_io::MotionModel motion;
    motion.step_s = 0.001;
    motion.t_s = {0.0, 0.001};
    motion.x_mm = {0.0, 0.01};
    motion.y_mm = {0.0, 0.0};
    motion.z_mm = {-1.0, -1.0};
    motion.vx_mm_s = {10.0, 10.0};
    motion.vy_mm_s = motion.vz_mm_s = {0.0, 0.0};
    motion.spindle_rpm = {6000.0, 6000.0};
    motion.spindle_angle_deg = {0.0, 36.0};
    motion.block = {0, 0};
    motion.block_names = {"N10"};
    motion.session_start = {0};
    cutload::force_model::Prediction p;
    p.blocks.resize(1);
    // 240 000 rays, 7.7 MB: several of the pieces the store writes the stock in.
    p.final_stock = cutload::force_model::make_stock({{0, 0, -5}, {60, 40, 0}}, 0.1);
    const std::string stock_bytes = cutload::force_model::save_stock_bytes(*p.final_stock);

    std::atomic<bool> cancel{true};
    const std::int64_t cancelled = claimed();
    REQUIRE_THROWS_AS(cutload::server::store_result(*s, cancelled, motion, p, nullptr, true, &cancel),
                      cutload::force_model::Cancelled);
    REQUIRE(s->runs().status(cancelled)->state == cutload::db::JobState::Running);   // the pool finishes it as cancelled
    REQUIRE(s->runs().blocks(cancelled, 0, std::nullopt, 10).empty());
    REQUIRE_FALSE(s->runs().has_final_stock(cancelled));

    cancel = false;
    const std::int64_t stored = claimed();
    cutload::server::store_result(*s, stored, motion, p, nullptr, true, &cancel);
    REQUIRE(s->runs().status(stored)->state == cutload::db::JobState::Done);
    REQUIRE(s->runs().blocks(stored, 0, std::nullopt, 10).size() == 1);
    // The stock went into the row in pieces (SQLite's blob handle): the same bytes as in one piece.
    std::string read_back;
    REQUIRE(s->runs().read_final_stock(stored, [&](std::span<const unsigned char> b) { read_back.assign(b.begin(), b.end()); }));
    CHECK(read_back == stock_bytes);
}

TEST_CASE("job stop: a final stock whose writer gives other than the bytes announced is refused and leaves no row") {
    TempDir dir;
    auto store = cutload::db::Store::open(store_location(dir.path(), "store.db"));
    store->migrate();
    auto s = store->session();
    cutload::db::NewRun nr;
    nr.inputs_json = "{}";
    nr.created_at = cutload::db::now_iso();
    const std::int64_t id = s->runs().create(nr);
    // 3 MiB announced: the SQLite store takes them in 1 MiB pieces, so the short writer has
    // written pieces into the row before the count fails.
    const std::uint64_t announced = 3u << 20;
    const auto writes = [](std::uint64_t n) {
        return [n](std::ostream& out) {
            const std::string piece(4096, 'x');
            for (std::uint64_t at = 0; at < n; at += piece.size())
                out.write(piece.data(), static_cast<std::streamsize>(std::min<std::uint64_t>(piece.size(), n - at)));
        };
    };
    for (const std::uint64_t given : {announced - 5000, announced + 1}) {
        cutload::db::Transaction tx(*s);
        CHECK_THROWS_WITH(s->runs().set_final_stock(id, announced, writes(given)),
                          Catch::Contains(std::to_string(announced)));
        // The caller's transaction ends without a commit: nothing of the stock stays.
    }
    CHECK_FALSE(s->runs().has_final_stock(id));
    {
        cutload::db::Transaction tx(*s);
        s->runs().set_final_stock(id, announced, writes(announced));
        tx.commit();
    }
    std::uint64_t stored = 0;
    REQUIRE(s->runs().read_final_stock(id, [&](std::span<const unsigned char> b) { stored = b.size(); }));
    CHECK(stored == announced);
}
