// The stock format in memory (the service keeps stocks in its database): the same bytes as the
// file, the same stock back, the same refusals naming the source.
#include "force_model/engine.hpp"
#include "force_model/engine_fixtures.hpp"

#include <catch2/catch.hpp>

#include <filesystem>
#include <fstream>
#include <iterator>

using namespace cutload;
using namespace cutload::enginetest;

namespace {

std::string file_bytes(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

}  // namespace

TEST_CASE("stock bytes are the stock file's bytes and load to the same stock", "[stock]") {
    // A slot along X with walls on both sides, and a crossing slot one level lower: cut rays,
    // untouched rays and both wall lists are all in the bytes.
    const auto m = legs_motion({-10, 10, 7}, {{{50, 10, 7}, 3000, "N10"}, {{50, 10, 12}, 3000, "N20"},
                                               {{20, -10, 12}, 3000, "N30"}, {{20, -10, 6}, 3000, "N40"},
                                               {{20, 30, 6}, 3000, "N50"}});
    const auto p = run_on(m, base_spec(), force_model::Device::Cpu);
    const force_model::Stock& stock = *p.final_stock;

    const std::string path = (std::filesystem::temp_directory_path() / "cutload_stock_bytes.bin").string();
    force_model::save_stock(stock, path);
    const std::string bytes = force_model::save_stock_bytes(stock);
    CHECK(bytes == file_bytes(path));   // one format: the file is the bytes
    CHECK(force_model::stock_file_bytes(stock) == bytes.size());   // what a store sets aside for them
    // A header, one decoded ray per cell, two wall lists with their counts and the checksum.
    CHECK(bytes.size() > stock.rays() * sizeof(kernels::Ray) + 2 * 8 + 8);

    const auto from_bytes = force_model::load_stock_bytes(bytes, "stock of run 7");
    const auto from_file = force_model::load_stock(path);
    REQUIRE(from_bytes->rays() == stock.rays());
    std::size_t differing = 0, cut = 0;
    for (std::size_t r = 0; r < stock.rays(); ++r) {
        differing += from_bytes->ray(r) == stock.ray(r) && from_file->ray(r) == stock.ray(r) ? 0 : 1;
        cut += stock.untouched(r) ? 0 : 1;
    }
    CHECK(cut > 1000);
    CHECK(differing == 0);
    // Saved again, each is byte for byte what was loaded: walls and all.
    CHECK(force_model::save_stock_bytes(*from_bytes) == bytes);
    CHECK(force_model::save_stock_bytes(*from_file) == bytes);
    CHECK(force_model::stock_volume_mm3(*from_bytes) == force_model::stock_volume_mm3(stock));
    std::filesystem::remove(path);
}

TEST_CASE("stock bytes that are not a whole stock are refused naming their source", "[stock]") {
    const auto m = legs_motion({-10, 10, 7}, {{{50, 10, 7}, 3000, "N10"}});
    const auto p = run_on(m, base_spec(), force_model::Device::Cpu);
    const std::string bytes = force_model::save_stock_bytes(*p.final_stock);

    std::string flipped = bytes;
    flipped[flipped.size() / 2] ^= 0x7f;
    CHECK_THROWS_WITH(force_model::load_stock_bytes(flipped, "base_run 3"),
                      Catch::StartsWith("base_run 3: ") && Catch::Contains("checksum"));
    CHECK_THROWS_WITH(force_model::load_stock_bytes(std::string_view(bytes).substr(0, bytes.size() / 3), "base_run 3"),
                      Catch::StartsWith("base_run 3: ") && Catch::Contains("truncated"));
    CHECK_THROWS_WITH(force_model::load_stock_bytes(bytes + "x", "base_run 3"), Catch::Contains("trailing bytes"));
    CHECK_THROWS_WITH(force_model::load_stock_bytes("", "base_run 3"), Catch::Contains("magic"));
    CHECK_THROWS_WITH(force_model::load_stock_bytes("not a stock at all, just text padding padding padding padding", "x"),
                      Catch::Contains("magic"));
}
