// Internal to app: a prediction's rows handed to their consumer (FORCES.csv, FORCES.bin, the
// service's force series) on a thread of their own, so the engine walks the next rows while the
// last ones are encoded and written. Encoding is a large share of a long run's time: an hour of
// roughing took 117-129 s with FORCES.csv against 69-74 s with FORCES.bin, on one thread.
#pragma once

#include "force_model/force_model.hpp"

#include <condition_variable>
#include <cstddef>
#include <deque>
#include <exception>
#include <functional>
#include <mutex>
#include <span>
#include <thread>
#include <vector>

namespace cutload::app {

class RowsPipe {
public:
    // Gets the pipe's own copy of each piece, in order, on the pipe's thread; it may change them.
    using Consumer = std::function<void(std::span<force_model::ForceSample> rows)>;
    // At most `depth` pieces wait for the consumer (memory: depth pieces of rows, copied).
    explicit RowsPipe(Consumer consume, std::size_t depth = 2);
    RowsPipe(const RowsPipe&) = delete;
    RowsPipe& operator=(const RowsPipe&) = delete;
    // Stops the consumer's thread; pieces not yet consumed are dropped (the run failed).
    ~RowsPipe();

    // Copies the rows and queues them; waits while `depth` pieces are queued. Rethrows what the
    // consumer threw (a full disk), so the engine stops at its next piece.
    void push(std::span<const force_model::ForceSample> rows);
    // Runs `task` on the consumer's thread after the pieces pushed before it and before those pushed
    // after it (what the consumer's state needs in order with the rows: a session's start).
    void post(std::function<void()> task);
    // Returns once every piece is consumed; rethrows what the consumer threw.
    void finish();

private:
    struct Item {
        std::vector<force_model::ForceSample> rows;
        std::function<void()> task;   // set: a task, not rows
    };
    void enqueue(Item item);
    void consume_loop();
    void rethrow_locked();
    // Waits until fewer than depth_ items are queued; rethrows the consumer's error.
    void wait_for_slot(std::unique_lock<std::mutex>& lock);

    Consumer consume_;
    std::size_t depth_;
    std::mutex mutex_;
    std::condition_variable changed_;
    std::deque<Item> queued_;
    std::vector<std::vector<force_model::ForceSample>> spare_;   // consumed pieces' buffers, reused
    std::exception_ptr error_;
    bool busy_ = false;    // the consumer holds a piece
    bool closing_ = false;
    std::thread thread_;   // last: started once the members above exist
};

}  // namespace cutload::app
