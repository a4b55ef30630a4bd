#include "rows_pipe.hpp"

#include <algorithm>
#include <utility>

namespace cutload::app {

RowsPipe::RowsPipe(Consumer consume, std::size_t depth)
    : consume_(std::move(consume)), depth_(std::max<std::size_t>(1, depth)), thread_([this] { consume_loop(); }) {}

RowsPipe::~RowsPipe() {
    {
        std::lock_guard lock(mutex_);
        closing_ = true;
        queued_.clear();
    }
    changed_.notify_all();
    thread_.join();
}

void RowsPipe::rethrow_locked() {
    if (error_) std::rethrow_exception(error_);
}

void RowsPipe::wait_for_slot(std::unique_lock<std::mutex>& lock) {
    changed_.wait(lock, [&] { return error_ || queued_.size() < depth_; });
    rethrow_locked();
}

void RowsPipe::push(std::span<const force_model::ForceSample> rows) {
    Item item;
    {
        std::unique_lock lock(mutex_);
        wait_for_slot(lock);
        if (!spare_.empty()) {
            item.rows = std::move(spare_.back());
            spare_.pop_back();
        }
    }
    // Pieces differ by a few rows (the engine hands them out at interval ends); a buffer grown to
    // each new largest one by exactly its size was reallocated piece after piece, and each
    // reallocation of a few hundred kB faulted in fresh pages (about 30 us each on a VM).
    if (item.rows.capacity() < rows.size()) item.rows.reserve(rows.size() + rows.size() / 4);
    item.rows.assign(rows.begin(), rows.end());
    enqueue(std::move(item));
}

void RowsPipe::post(std::function<void()> task) {
    Item item;
    item.task = std::move(task);
    {
        std::unique_lock lock(mutex_);
        wait_for_slot(lock);
    }
    enqueue(std::move(item));
}

void RowsPipe::enqueue(Item item) {
    {
        std::lock_guard lock(mutex_);
        queued_.push_back(std::move(item));
    }
    changed_.notify_all();
}

void RowsPipe::finish() {
    std::unique_lock lock(mutex_);
    changed_.wait(lock, [&] { return error_ || (queued_.empty() && !busy_); });
    rethrow_locked();
}

void RowsPipe::consume_loop() {
    std::unique_lock lock(mutex_);
    for (;;) {
        changed_.wait(lock, [&] { return closing_ || !queued_.empty(); });
        if (closing_) return;
        Item item = std::move(queued_.front());
        queued_.pop_front();
        busy_ = true;
        lock.unlock();
        changed_.notify_all();   // a slot is free
        std::exception_ptr failed;
        try {
            if (item.task) item.task();
            else consume_(item.rows);
        } catch (...) {
            failed = std::current_exception();
        }
        lock.lock();
        busy_ = false;
        if (failed) {
            error_ = failed;
            queued_.clear();
        } else if (!item.task && spare_.size() < depth_) {
            spare_.push_back(std::move(item.rows));
        }
        changed_.notify_all();
        if (failed) {
            // Nothing more is consumed; push() and finish() report the error.
            changed_.wait(lock, [&] { return closing_; });
            return;
        }
    }
}

}  // namespace cutload::app
