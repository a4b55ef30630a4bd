// Released zero pages are reused (force_model/zero_pages.cpp): a mapping handed back is cleared
// and given to the next request of its size, so what a run wrote must never show through in the
// next run's stock, its walls or its top map.
#include "engine_fixtures.hpp"
#include "force_model/stock.hpp"

#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <cstring>

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
