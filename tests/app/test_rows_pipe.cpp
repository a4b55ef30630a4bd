// app::RowsPipe: a prediction's rows reach their consumer on another thread in order, whole, and a
// consumer's failure stops the producer at its next piece.
#include "app/rows_pipe.hpp"

#include <catch2/catch.hpp>

#include <atomic>
#include <chrono>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

using namespace cutload;

namespace {

std::vector<force_model::ForceSample> piece(std::size_t first, std::size_t n) {
    std::vector<force_model::ForceSample> rows(n);
    for (std::size_t k = 0; k < n; ++k) {
        rows[k].t_s = double(first + k) * 1e-4;
        rows[k].fx_N = float(first + k);
    }
    return rows;
}

}  // namespace

TEST_CASE("rows pipe: every row arrives once, in order, with what the consumer changed staying its own",
          "[app][rows_pipe]") {
    std::vector<double> seen_t;
    std::vector<float> seen_fx;
    {
        app::RowsPipe pipe([&](std::span<force_model::ForceSample> rows) {
            // A slow consumer: the producer must wait rather than drop or reorder.
            std::this_thread::sleep_for(std::chrono::microseconds(200));
            for (auto& r : rows) {
                seen_t.push_back(r.t_s);
                seen_fx.push_back(r.fx_N);
                r.fx_N = -1;   // its own copy: the producer's rows stay as they were
            }
        });
        std::size_t next = 0;
        for (std::size_t n : {1u, 7u, 1000u, 3u, 65536u, 2u, 0u, 500u}) {
            const auto rows = piece(next, n);
            pipe.push(rows);
            for (const auto& r : rows) REQUIRE(r.fx_N >= 0);
            next += n;
        }
        pipe.finish();
        REQUIRE(seen_t.size() == next);
    }
    for (std::size_t k = 0; k < seen_t.size(); ++k) {
        REQUIRE(seen_t[k] == double(k) * 1e-4);
        REQUIRE(seen_fx[k] == float(k));
    }
}

TEST_CASE("rows pipe: a consumer's error reaches the producer, and nothing after it is consumed",
          "[app][rows_pipe]") {
    std::atomic<int> calls{0};
    app::RowsPipe pipe([&](std::span<force_model::ForceSample>) {
        if (++calls == 2) throw std::runtime_error("disk full");
    });
    bool thrown = false;
    try {
        for (int k = 0; k < 50; ++k) pipe.push(piece(std::size_t(k) * 10, 10));
        pipe.finish();
    } catch (const std::runtime_error& e) {
        thrown = true;
        CHECK(std::string(e.what()) == "disk full");
    }
    CHECK(thrown);
    CHECK(calls == 2);
    CHECK_THROWS_WITH(pipe.finish(), "disk full");
}

TEST_CASE("rows pipe: dropped with pieces still queued (a run that failed), it stops without consuming them",
          "[app][rows_pipe]") {
    std::atomic<int> calls{0};
    std::atomic<bool> release{false};
    std::thread releaser;
    {
        app::RowsPipe pipe([&](std::span<force_model::ForceSample>) {
            ++calls;
            while (!release) std::this_thread::sleep_for(std::chrono::milliseconds(1));
        });
        pipe.push(piece(0, 5));
        while (calls == 0) std::this_thread::sleep_for(std::chrono::milliseconds(1));
        pipe.push(piece(5, 5));
        pipe.push(piece(10, 5));
        // The consumer is held in the first piece while the pipe is dropped; it lets go later.
        releaser = std::thread([&] {
            std::this_thread::sleep_for(std::chrono::milliseconds(50));
            release = true;
        });
    }
    releaser.join();
    CHECK(calls == 1);
}

TEST_CASE("rows pipe: a posted task runs after the pieces pushed before it and before those after it",
          "[app][rows_pipe]") {
    std::vector<std::string> events;   // touched only on the pipe's thread until finish()
    app::RowsPipe pipe([&](std::span<force_model::ForceSample> rows) {
        std::this_thread::sleep_for(std::chrono::microseconds(300));
        events.push_back("rows " + std::to_string(rows.size()));
    });
    pipe.push(piece(0, 3));
    pipe.post([&] { events.push_back("session 1"); });
    pipe.push(piece(3, 4));
    pipe.push(piece(7, 5));
    pipe.post([&] { events.push_back("session 2"); });
    pipe.push(piece(12, 6));
    pipe.finish();
    CHECK(events == std::vector<std::string>{"rows 3", "session 1", "rows 4", "rows 5", "session 2", "rows 6"});
}
