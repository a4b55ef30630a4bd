// ZeroPages and the process-wide pool of released mappings it draws from.
//
// Why a pool: a fresh mapping costs a page fault on every page a run touches, and on a virtual
// machine a fault costs several microseconds (bench_force: about a fifth of a PoCL prediction's CPU
// time went to faults on the stock, its walls and its top map). A released mapping is kept and
// handed to the next request of the same size, made all zero again first (touching only what the
// run touched), so the second and later predictions of a process (the service, a worker, a bench)
// find their pages already mapped. The clearing is part of the next prediction's set-up phase.
//
// Why pages are made writable before they are read (prepare_writable): a page first *read* is
// mapped to the OS's shared zero page, and the first write to it then replaces that mapping (copy
// on write), after which the OS must flush the old mapping from the TLB of every CPU running the
// process: an inter-processor interrupt per page, tens of microseconds of both cores on a virtual
// machine. The engine reads a ray before it writes it (an engagement looks at the stock before its
// removal cuts it; the host compares a ray's top before it stores a new one), so every page it cut
// went through that: about 2300 flushes on bench_startup's 10 s contour, an eighth of `cutload
// predict`'s CPU time. A page first *written* costs one ordinary fault and no flush, so the engine
// asks (MADV_POPULATE_WRITE, Linux 5.14) for the pages it is about to read and cut. Which pages
// were made writable travels with a pooled mapping, so a later prediction does not ask again.
#include "stock.hpp"

#include <malloc.h>
#include <sys/mman.h>
#include <sys/sysinfo.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <new>
#include <utility>
#include <vector>

#ifndef MADV_POPULATE_WRITE
#define MADV_POPULATE_WRITE 23
#endif

namespace cutload::force_model {

namespace {

std::size_t page_bytes() {
    static const std::size_t page = std::size_t(sysconf(_SC_PAGESIZE));
    return page;
}

std::size_t round_to_pages(std::size_t bytes) {
    const std::size_t page = page_bytes();
    return (bytes + page - 1) / page * page;
}

bool page_is_zero(const unsigned char* p, std::size_t n) {
    const auto* w = reinterpret_cast<const std::uint64_t*>(p);
    std::uint64_t any = 0;
    for (std::size_t k = 0; k < n / 8; ++k) any |= w[k];
    return any == 0;
}

}  // namespace

// Pages the kernel reports resident are read (the shared zero page, where a run only looked, is
// cache-hot) and cleared where written. A page it reports absent was never touched, or is in swap:
// on a machine with swap, absent pages are dropped with MADV_DONTNEED, which discards any copy in
// swap too (a call per run of them; without swap there is no copy to discard).
bool clear_zero_pages(void* mapping, std::size_t len, bool machine_has_swap) {
    auto* base = static_cast<unsigned char*>(mapping);
    const std::size_t page = page_bytes(), pages = len / page;
    std::vector<unsigned char> resident(pages);
    if (mincore(base, len, resident.data()) != 0) return false;
    std::size_t run = pages;   // first page of the current run of absent pages
    for (std::size_t k = 0; k <= pages; ++k) {
        const bool absent = k < pages && !(resident[k] & 1);
        if (absent) {
            if (machine_has_swap && run == pages) run = k;
            continue;
        }
        if (run != pages) {
            if (madvise(base + run * page, (k - run) * page, MADV_DONTNEED) != 0) return false;
            run = pages;
        }
        if (k < pages && !page_is_zero(base + k * page, page)) std::memset(base + k * page, 0, page);
    }
    return true;
}

namespace {

// False when the kernel refused a call: the mapping is then unmapped.
bool clear_mapping(unsigned char* base, std::size_t len) {
    struct sysinfo info {};
    if (sysinfo(&info) != 0) return false;
    return clear_zero_pages(base, len, info.totalswap != 0);
}

// Released mappings kept for reuse, newest last. Bounded by CUTLOAD_ZERO_POOL_MB (default 256;
// 0 turns the pool off): what it keeps is resident memory the process holds while idle.
class Pool {
public:
    // A kept mapping of exactly `len` bytes, made all zero; null when there is none. Clearing
    // happens here, not on release, so a process that ends after its one prediction (the CLI) never
    // pays for it.
    // `writable` receives which of its pages were made writable (ZeroPages::prepare_writable).
    void* take(std::size_t len, std::vector<std::uint64_t>& writable) {
        void* p = nullptr;
        {
            std::lock_guard lock(mutex_);
            for (std::size_t k = kept_.size(); k-- > 0;)
                if (kept_[k].len == len) {
                    p = kept_[k].data;
                    writable = std::move(kept_[k].writable);
                    kept_.erase(kept_.begin() + std::ptrdiff_t(k));
                    bytes_ -= len;
                    break;
                }
        }
        if (p && !clear_mapping(static_cast<unsigned char*>(p), len)) {
            munmap(p, len);
            writable.clear();
            return nullptr;
        }
        return p;
    }

    void give(void* data, std::size_t len, std::vector<std::uint64_t>&& writable) {
        if (len > limit_bytes()) {
            munmap(data, len);
            return;
        }
        std::vector<Mapping> drop;
        {
            std::lock_guard lock(mutex_);
            kept_.push_back({data, len, std::move(writable)});
            bytes_ += len;
            while (bytes_ > limit_bytes()) {   // oldest first
                drop.push_back(kept_.front());
                bytes_ -= kept_.front().len;
                kept_.erase(kept_.begin());
            }
        }
        for (const Mapping& m : drop) munmap(m.data, m.len);
    }

private:
    struct Mapping {
        void* data;
        std::size_t len;
        // Kept through clear_mapping, which leaves written pages resident. With swap a page may have
        // been dropped since: it is then only faulted in the slow way again.
        std::vector<std::uint64_t> writable;
    };

    static std::size_t limit_bytes() {
        static const std::size_t limit = [] {
            const char* v = std::getenv("CUTLOAD_ZERO_POOL_MB");
            char* end = nullptr;
            const long long mb = v && *v ? std::strtoll(v, &end, 10) : 256;
            if (v && *v && (*end != '\0' || mb < 0)) return std::size_t(256) << 20;   // unreadable: the default
            return std::size_t(std::min<long long>(mb, 1 << 20)) << 20;
        }();
        return limit;
    }

    std::mutex mutex_;
    std::vector<Mapping> kept_;
    std::size_t bytes_ = 0;
};

Pool& pool() {
    static Pool* p = new Pool();   // never destroyed: mappings may be released during static destruction
    return *p;
}

}  // namespace

bool keep_freed_heap_for_next_prediction() {
#ifdef __GLIBC__
    // Setting either threshold stops glibc from moving both as blocks are freed, so the trim
    // threshold is set only once the mmap one took. 32 MiB is the largest mmap threshold every
    // 64-bit glibc accepts (mallopt(3)); as much free heap kept covers a prediction's rows and
    // batches without holding more.
    if (mallopt(M_MMAP_THRESHOLD, 32 << 20) != 1) return false;
    return mallopt(M_TRIM_THRESHOLD, 32 << 20) == 1;
#else
    return false;
#endif
}

ZeroPages::ZeroPages(std::size_t bytes) : bytes_(bytes) {
    if (bytes == 0) return;
    const std::size_t len = round_to_pages(bytes);
    void* p = pool().take(len, writable_);
    if (!p) p = mmap(nullptr, len, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (p == MAP_FAILED) throw std::bad_alloc();
    data_ = p;
}

ZeroPages::ZeroPages(const ZeroPages& other) : ZeroPages(other.bytes_) {
    const std::size_t page = page_bytes();
    const auto* src = static_cast<const unsigned char*>(other.data_);
    auto* dst = static_cast<unsigned char*>(data_);
    for (std::size_t at = 0; at < bytes_; at += page) {
        const std::size_t n = std::min(page, bytes_ - at);
        if (std::any_of(src + at, src + at + n, [](unsigned char b) { return b != 0; })) std::memcpy(dst + at, src + at, n);
    }
}

ZeroPages::ZeroPages(ZeroPages&& other) noexcept
    : data_(std::exchange(other.data_, nullptr)), bytes_(std::exchange(other.bytes_, 0)),
      writable_(std::move(other.writable_)) {
    other.writable_.clear();
}

ZeroPages& ZeroPages::operator=(ZeroPages&& other) noexcept {
    if (this != &other) {
        release();
        data_ = std::exchange(other.data_, nullptr);
        bytes_ = std::exchange(other.bytes_, 0);
        writable_ = std::move(other.writable_);
        other.writable_.clear();
    }
    return *this;
}

ZeroPages::~ZeroPages() { release(); }

void ZeroPages::release() noexcept {
    if (!data_) return;
    try {
        pool().give(data_, round_to_pages(bytes_), std::move(writable_));
    } catch (...) {   // the pool could not grow its list: the mapping is simply returned
        munmap(data_, round_to_pages(bytes_));
    }
    data_ = nullptr;
    bytes_ = 0;
    writable_.clear();
}

namespace {

std::atomic<bool> populate_supported{true};   // false once the OS refused (Linux < 5.14)

}  // namespace

void ZeroPages::prepare_writable(std::size_t begin, std::size_t end) {
    end = std::min(end, bytes_);
    if (!data_ || begin >= end || !populate_supported.load(std::memory_order_relaxed)) return;
    const std::size_t page = page_bytes(), p1 = (end + page - 1) / page;
    if (writable_.empty()) writable_.assign((round_to_pages(bytes_) / page + 63) / 64, 0);
    auto* base = static_cast<unsigned char*>(data_);
    std::size_t run = p1;   // first page of the current run of pages not yet made writable
    for (std::size_t p = begin / page; p <= p1; ++p) {
        if (p < p1 && !(writable_[p / 64] >> (p % 64) & 1)) {
            if (run == p1) run = p;
            continue;
        }
        if (run == p1) continue;
        if (madvise(base + run * page, (p - run) * page, MADV_POPULATE_WRITE) == 0) {
            for (std::size_t q = run; q < p; ++q) writable_[q / 64] |= std::uint64_t(1) << (q % 64);
        } else if (errno == EINVAL) {
            // An OS without the request: pages fault in as they always did. Out of memory or a
            // signal: the same, page by page, when they are touched.
            populate_supported.store(false, std::memory_order_relaxed);
            return;
        }
        run = p1;
    }
}

void ZeroPages::prepare_writable_rows(std::size_t row_bytes, std::size_t begin, std::size_t end, std::size_t j0,
                                      std::size_t j1) {
    if (begin >= end || j0 >= j1) return;
    // Rows whose gaps are under a page are one range: a request per run of pages, not per row.
    if (end - begin + page_bytes() >= row_bytes) {
        prepare_writable(j0 * row_bytes + begin, (j1 - 1) * row_bytes + end);
        return;
    }
    for (std::size_t j = j0; j < j1; ++j) prepare_writable(j * row_bytes + begin, j * row_bytes + end);
}

}  // namespace cutload::force_model
