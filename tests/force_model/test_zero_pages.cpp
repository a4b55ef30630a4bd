// Released zero pages are reused (force_model/zero_pages.cpp): a mapping handed back is cleared
// and given to the next request of its size, so what a run wrote must never show through in the
// next run's stock, its walls or its top map.
#include "engine_fixtures.hpp"
#include "force_model/stock.hpp"

#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <vector>

using namespace cutload;
using namespace cutload::enginetest;

namespace {

bool all_zero(const force_model::ZeroPages& z) {
    const auto* p = static_cast<const unsigned char*>(z.data());
    return std::all_of(p, p + z.bytes(), [](unsigned char b) { return b == 0; });
}

}  // namespace

TEST_CASE("a released mapping comes back all zero to the next request of its size", "[stock][zero_pages]") {
    const std::size_t page = std::size_t(sysconf(_SC_PAGESIZE));
    const std::size_t bytes = 97 * page + 123;   // not a whole number of pages
    void* first_address = nullptr;
    {
        force_model::ZeroPages z(bytes);
        REQUIRE(all_zero(z));   // reads only: every page is now mapped, most never written
        auto* p = static_cast<unsigned char*>(z.data());
        // Written: the first byte, a page's last byte, a whole page, the mapping's last byte, and a
        // byte past the request (the rest of the last page is part of the mapping).
        p[0] = 1;
        p[5 * page - 1] = 0xff;
        std::memset(p + 40 * page, 0x5a, page);
        p[bytes - 1] = 7;
        p[97 * page + 200] = 9;
        first_address = z.data();
    }
    force_model::ZeroPages again(bytes);
    CHECK(again.data() == first_address);   // the pool handed the same mapping back
    CHECK(all_zero(again));
    const auto* p = static_cast<const unsigned char*>(again.data());
    CHECK(p[97 * page + 200] == 0);

    // A request of another size never gets it.
    force_model::ZeroPages other(bytes + 2 * page);
    CHECK(other.data() != again.data());
    CHECK(all_zero(other));

    // Moving into a mapping releases the one it held; that one comes back clear too.
    force_model::ZeroPages moved(bytes);
    static_cast<unsigned char*>(moved.data())[3 * page] = 4;
    void* released = moved.data();
    moved = force_model::ZeroPages(bytes + 2 * page);
    force_model::ZeroPages reused(bytes);
    CHECK(reused.data() == released);
    CHECK(all_zero(reused));
}

TEST_CASE("predictions that reuse a released stock cut the same as the first", "[engine][stock][zero_pages]") {
    // The first run keeps its stock; the runs between drop theirs, so the last one cuts in memory a
    // run before it cut (stock, walls, tops). Its rows and final stock must equal the first's.
    const auto spec = base_spec();
    const auto m = legs_motion({-6, 6, 7}, {{{46, 6, 7}, 3000, "N10"}, {{46, 12, 7}, 3000, "N20"}, {{-6, 12, 7}, 3000, "N30"}});
    for (const force_model::Device d : {force_model::Device::Cpu, force_model::Device::OpenCL}) {
        if (d == force_model::Device::OpenCL && !opencl_available()) {
            WARN("no OpenCL device: the CPU path only");
            continue;
        }
        force_model::PredictOptions o;
        o.device = d;
        std::string first_stock;
        std::vector<force_model::ForceSample> first_rows;
        {
            const force_model::Prediction first = force_model::predict(m, spec, o);
            REQUIRE(first.final_stock);
            first_stock = force_model::save_stock_bytes(*first.final_stock);
            first_rows = first.samples;
        }
        o.keep_final_stock = false;
        for (int k = 0; k < 2; ++k) (void)force_model::predict(m, spec, o);
        o.keep_final_stock = true;
        const force_model::Prediction last = force_model::predict(m, spec, o);
        REQUIRE(last.final_stock);
        CHECK(force_model::save_stock_bytes(*last.final_stock) == first_stock);
        REQUIRE(last.samples.size() == first_rows.size());
        std::size_t differing = 0;
        for (std::size_t i = 0; i < first_rows.size(); ++i) {
            const auto &a = first_rows[i], &b = last.samples[i];
            if (a.fx_N != b.fx_N || a.fy_N != b.fy_N || a.fz_N != b.fz_N || a.removed_mm3 != b.removed_mm3) ++differing;
        }
        CHECK(differing == 0);
    }
}

TEST_CASE("clearing a mapping zeroes what was written, with and without swap on the machine", "[stock][zero_pages]") {
    const std::size_t page = std::size_t(sysconf(_SC_PAGESIZE));
    const std::size_t len = 64 * page;
    for (const bool swap : {false, true}) {
        void* m = mmap(nullptr, len, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
        REQUIRE(m != MAP_FAILED);
        auto* p = static_cast<unsigned char*>(m);
        // Written pages between runs of untouched and only-read ones.
        for (std::size_t k = 0; k < 64; k += 7) p[k * page + k] = static_cast<unsigned char>(k + 1);
        volatile unsigned char sink = 0;
        for (std::size_t k = 3; k < 64; k += 11) sink = sink + p[k * page];
        REQUIRE(force_model::clear_zero_pages(m, len, swap));
        CHECK(std::all_of(p, p + len, [](unsigned char b) { return b == 0; }));
        munmap(m, len);
    }
}

namespace {

// Pages of [data, data + pages * page) the OS has mapped (mincore: resident).
std::vector<bool> resident_pages(const void* data, std::size_t pages) {
    const std::size_t page = std::size_t(sysconf(_SC_PAGESIZE));
    std::vector<unsigned char> v(pages);
    REQUIRE(mincore(const_cast<void*>(data), pages * page, v.data()) == 0);
    std::vector<bool> out(pages);
    for (std::size_t k = 0; k < pages; ++k) out[k] = (v[k] & 1) != 0;
    return out;
}

}  // namespace

TEST_CASE("pages made writable keep what they hold, and only the pages asked for are mapped", "[stock][zero_pages]") {
    const std::size_t page = std::size_t(sysconf(_SC_PAGESIZE));
    // A size no other test asks for: a pooled mapping would come with its pages already mapped.
    constexpr std::size_t kPages = 173;
    force_model::ZeroPages z(kPages * page);
    auto* p = static_cast<unsigned char*>(z.data());
    std::memset(p + 2 * page, 0x5a, page);   // written before: must survive the request
    const std::vector<bool> before = resident_pages(p, kPages);
    CHECK(before[2]);
    CHECK(std::count(before.begin(), before.end(), true) == 1);

    // Bytes 100 to page + 10: pages 0 and 1.
    z.prepare_writable(100, page + 10);
    // Rows of 3 pages, bytes [100, 200) of rows 4..7: one page a row (12, 15, 18, 21), the rows'
    // gaps of two pages left alone.
    z.prepare_writable_rows(3 * page, 100, 200, 4, 8);
    // Rows of 1.5 pages, the whole width of rows 20..23: one range, pages 30..35.
    z.prepare_writable_rows(page + page / 2, 0, page + page / 2, 20, 24);
    // Past the mapping's end: clipped to its last page.
    z.prepare_writable((kPages - 1) * page, 2 * kPages * page);
    const std::vector<bool> after = resident_pages(p, kPages);
    // Linux before 5.14 has no MADV_POPULATE_WRITE: the pages then fault in when touched, as before.
    void* probe = mmap(nullptr, page, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    REQUIRE(probe != MAP_FAILED);
    const bool supported = madvise(probe, page, 23 /* MADV_POPULATE_WRITE */) == 0;
    munmap(probe, page);
    if (!supported) WARN("this kernel cannot populate pages for writing: only the contents are checked");
    for (std::size_t k = 0; k < kPages && supported; ++k) {
        const bool asked =
            k <= 2 || k == 12 || k == 15 || k == 18 || k == 21 || (k >= 30 && k <= 35) || k == kPages - 1;
        INFO("page " << k);
        CHECK(after[k] == asked);
    }
    CHECK(std::all_of(p + 2 * page, p + 3 * page, [](unsigned char b) { return b == 0x5a; }));
    CHECK(std::all_of(p, p + 2 * page, [](unsigned char b) { return b == 0; }));
    CHECK(std::all_of(p + 3 * page, p + kPages * page, [](unsigned char b) { return b == 0; }));
}

TEST_CASE("keep_freed_heap_for_next_prediction: glibc takes both thresholds, and a freed block stays with the process",
          "[zero_pages]") {
#ifdef __GLIBC__
    REQUIRE(force_model::keep_freed_heap_for_next_prediction());
    // A block the size of bench_force's rows, written and freed: its pages stay mapped and resident
    // for the next request. By default glibc maps a block this large on its own and unmaps it when
    // it is freed (mincore then fails with ENOMEM).
    constexpr std::size_t kBytes = 13u << 20;
    auto* block = static_cast<unsigned char*>(std::malloc(kBytes));
    REQUIRE(block != nullptr);
    std::memset(block, 1, kBytes);
    const std::size_t page = std::size_t(sysconf(_SC_PAGESIZE));
    unsigned char* first_page = block + (page - reinterpret_cast<std::uintptr_t>(block) % page) + page;
    const std::size_t pages = kBytes / page - 3;   // whole pages well inside the block
    std::free(block);
    std::vector<unsigned char> resident(pages);
    REQUIRE(mincore(first_page, pages * page, resident.data()) == 0);
    CHECK(std::all_of(resident.begin(), resident.end(), [](unsigned char r) { return (r & 1) != 0; }));
#else
    CHECK_FALSE(force_model::keep_freed_heap_for_next_prediction());
#endif
}
