// The store under several processes at once (issue 18): stores opened separately on one location,
// as separate `cutload` processes would, migrate it together and claim from one queue together.
// Runs on SQLite ("server: ...") and on PostgreSQL ("server-pg: ...").
#include "db/jobs.hpp"
#include "db/runs.hpp"
#include "db/store.hpp"
#include "harness.hpp"

#include <algorithm>
#include <set>
#include <thread>

using namespace cutload::test;
namespace db = cutload::db;

TEST_CASE("store: four stores migrating one new database at once all reach the schema version") {
    TempDir dir;
    const std::string location = store_location(dir.path(), "migrate.db");
    std::vector<int> reached(4, -1);
    std::vector<std::thread> threads;
    for (std::size_t i = 0; i < reached.size(); ++i)
        threads.emplace_back([&, i] { reached[i] = db::Store::open(location)->migrate(); });
    for (auto& t : threads) t.join();
    for (const int v : reached) REQUIRE(v == db::schema_version());
    // Migrated once: the tables hold what one store writes.
    auto store = db::Store::open(location, db::Store::Open::MustExist);
    REQUIRE(store->migrate() == db::schema_version());
    REQUIRE(store->session()->runs().list({}).empty());
}

TEST_CASE("store: claims from four stores at once hand out every queued job exactly once") {
    TempDir dir;
    const std::string location = store_location(dir.path(), "claims.db");
    constexpr int kJobs = 120;
    std::set<std::int64_t> queued;
    {
        auto store = db::Store::open(location);
        store->migrate();
        auto s = store->session();
        db::Transaction tx(*s);
        for (int i = 0; i < kJobs; ++i) {
            db::NewRun r;
            r.inputs_json = "{}";
            r.created_at = db::now_iso();
            queued.insert(s->runs().create(r));
        }
        tx.commit();
    }
    // Each thread is its own store (its own connections), as a separate process would be.
    std::vector<std::vector<std::int64_t>> claimed(4);
    std::vector<std::thread> threads;
    for (auto& mine : claimed)
        threads.emplace_back([&location, &mine] {
            auto store = db::Store::open(location);
            auto s = store->session();
            const std::string token = "claims/" + std::to_string(reinterpret_cast<std::uintptr_t>(&mine)) + "/";
            int n = 0;
            while (auto id = s->jobs().claim_oldest(db::kRunQueue, db::now_iso(), {token + std::to_string(++n), "9999-12-31T00:00:00.000Z"}))
                mine.push_back(*id);
        });
    for (auto& t : threads) t.join();

    std::multiset<std::int64_t> all;
    for (const auto& mine : claimed) all.insert(mine.begin(), mine.end());
    REQUIRE(all.size() == kJobs);
    REQUIRE(std::set<std::int64_t>(all.begin(), all.end()) == queued);   // each once, none missed
    for (const auto& mine : claimed) REQUIRE(std::is_sorted(mine.begin(), mine.end()));   // oldest first
    auto store = db::Store::open(location);
    auto s = store->session();
    REQUIRE(s->jobs().count(db::kRunQueue, {db::JobState::Running}) == kJobs);
    for (const auto id : queued) REQUIRE(s->runs().get(id)->attempts == 1);
    WARN("claims per store: " << claimed[0].size() << ", " << claimed[1].size() << ", " << claimed[2].size() << ", "
                              << claimed[3].size());
}

TEST_CASE("store: a claim is a lease: renewed it holds the job, ended it lets any process re-queue the job, and only the holder finishes it") {
    TempDir dir;
    const std::string location = store_location(dir.path(), "leases.db");
    auto store = db::Store::open(location);
    store->migrate();
    auto s = store->session();
    std::vector<std::int64_t> ids;
    for (int i = 0; i < 4; ++i) {
        db::NewRun r;
        r.inputs_json = "{}";
        r.created_at = db::now_iso();
        ids.push_back(s->runs().create(r));
    }
    // Two processes, A and B: A claims the first two runs, B the third. Times are fixed texts in
    // now_iso's format, so "ended" does not depend on the test's speed.
    const std::string t0 = "2026-01-01T00:00:00.000Z", t1 = "2026-01-01T00:00:30.000Z", t2 = "2026-01-01T00:01:00.000Z";
    REQUIRE(s->jobs().claim_oldest(db::kRunQueue, t0, {"A/1", t1}) == ids[0]);
    REQUIRE(s->jobs().claim_oldest(db::kRunQueue, t0, {"A/2", t1}) == ids[1]);
    REQUIRE(s->jobs().claim_oldest(db::kRunQueue, t0, {"B/1", t1}) == ids[2]);
    REQUIRE(s->jobs().holds(db::kRunQueue, ids[0], "A/1"));
    REQUIRE_FALSE(s->jobs().holds(db::kRunQueue, ids[0], "A/2"));
    REQUIRE_FALSE(s->jobs().holds(db::kRunQueue, ids[3], "A/1"));   // queued, nobody's

    // A renews (the prefix names its claims, not B's); B stops renewing, as a killed process does.
    const auto renew = [&](const std::string& prefix) {
        auto held = s->jobs().renew_leases(db::kRunQueue, prefix, t2);
        std::sort(held.begin(), held.end());
        return held;
    };
    REQUIRE(renew("A/") == std::vector<std::int64_t>{ids[0], ids[1]});
    // Nothing has ended at t1 (B's lease ends at t1, not before); after it, only B's run is re-queued.
    REQUIRE(s->jobs().requeue_expired(db::kRunQueue, 3, "cap", t1).requeued == 0);
    const db::Requeued r = s->jobs().requeue_expired(db::kRunQueue, 3, "cap", "2026-01-01T00:00:45.000Z");
    REQUIRE(r.requeued == 1);
    REQUIRE(r.failed == 0);
    REQUIRE(s->runs().get(ids[2])->state == db::JobState::Queued);
    REQUIRE(s->runs().get(ids[0])->state == db::JobState::Running);
    REQUIRE_FALSE(s->jobs().holds(db::kRunQueue, ids[2], "B/1"));

    // C claims it again: B, should it wake up, can neither finish it nor find it among its claims.
    REQUIRE(s->jobs().claim_oldest(db::kRunQueue, t1, {"C/1", t2}) == ids[2]);
    s->jobs().finish(db::kRunQueue, ids[2], db::JobState::Failed, std::string("B's late failure"), t1, std::string("B/1"));
    REQUIRE(s->runs().get(ids[2])->state == db::JobState::Running);
    REQUIRE(renew("B/").empty());
    REQUIRE(s->runs().get(ids[2])->attempts == 2);
    s->jobs().finish(db::kRunQueue, ids[2], db::JobState::Failed, std::string("C's failure"), t1, std::string("C/1"));
    REQUIRE(s->runs().get(ids[2])->state == db::JobState::Failed);

    // Cancelled in the store by another process: A's next renewal no longer finds it.
    REQUIRE(s->jobs().cancel_running(db::kRunQueue, ids[1], t1));
    REQUIRE_FALSE(s->jobs().cancel_running(db::kRunQueue, ids[1], t1));
    REQUIRE(renew("A/") == std::vector<std::int64_t>{ids[0]});

    // At the attempt cap an ended lease fails the job with the reason instead.
    const db::Requeued capped = s->jobs().requeue_expired(db::kRunQueue, 1, "died once too often", "2026-01-01T00:02:00.000Z");
    REQUIRE(capped.failed == 1);
    REQUIRE(capped.requeued == 0);
    REQUIRE(s->runs().get(ids[0])->state == db::JobState::Failed);
    REQUIRE(s->runs().get(ids[0])->error == std::optional<std::string>("died once too often"));
}

TEST_CASE("store: a job queued by one process signals the others at its commit, and not at a rollback") {
    TempDir dir;
    const std::string location = store_location(dir.path(), "signal.db");
    auto queuer = db::Store::open(location);
    queuer->migrate();
    auto listener = db::Store::open(location);
    auto signal = listener->job_signal();
    if (!on_postgres()) {
        // One process per SQLite store: its server wakes its own workers.
        REQUIRE(signal == nullptr);
        return;
    }
    REQUIRE(signal != nullptr);
    REQUIRE_FALSE(signal->wait(0.2));   // nothing queued yet
    auto s = queuer->session();
    const auto queue_one = [&](bool commit) {
        db::Transaction tx(*s);
        db::NewRun r;
        r.inputs_json = "{}";
        r.created_at = db::now_iso();
        s->runs().create(r);
        if (commit) tx.commit();
    };
    queue_one(false);
    REQUIRE_FALSE(signal->wait(0.3));   // rolled back: no job, no signal
    queue_one(true);
    const auto t0 = std::chrono::steady_clock::now();
    REQUIRE(signal->wait(5));
    const double waited_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    CHECK(waited_s < 1.0);
    REQUIRE_FALSE(signal->wait(0.2));   // consumed
    // A graceful stop's re-queue signals too: the job is someone else's to take.
    const auto id = s->jobs().claim_oldest(db::kRunQueue, db::now_iso(), {"A/1", "9999-12-31T00:00:00.000Z"});
    REQUIRE(id);
    s->jobs().finish(db::kRunQueue, *id, db::JobState::Queued, std::nullopt, db::now_iso(), std::string("A/1"));
    REQUIRE(signal->wait(5));
}
