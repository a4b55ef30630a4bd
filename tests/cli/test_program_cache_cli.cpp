// The on-disk OpenCL program cache (kernels/program_cache.hpp): entries round-trip and anything
// damaged or foreign is ignored; the folder must be private; and `cutload predict --device opencl`
// gives byte-identical forces whether its programs were built from source, loaded from the cache,
// or rebuilt over a damaged entry.
#include "cli/run_cli.hpp"
#include "kernels/opencl_runtime.hpp"
#include "kernels/program_cache.hpp"

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sys/stat.h>

using namespace cutload;
using clitest::Env;
namespace fs = std::filesystem;

namespace {

std::string slurp(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), {}};
}

std::vector<fs::path> entries(const fs::path& dir) {
    std::vector<fs::path> out;
    if (fs::exists(dir))
        for (const auto& e : fs::directory_iterator(dir)) out.push_back(e.path());
    std::sort(out.begin(), out.end());
    return out;
}

}  // namespace

TEST_CASE("program cache entries round-trip, and a damaged or foreign entry is not loaded", "[cli][opencl][cache]") {
    const fs::path dir = clitest::scratch("program_cache_entries");
    const std::string key = "cutload OpenCL program\nsource:\n__kernel void k() {}";
    const std::vector<unsigned char> binary{1, 2, 3, 250, 0, 7, 9};
    REQUIRE(kernels::store_program_binary(dir.string(), key, binary));
    CHECK(kernels::load_program_binary(dir.string(), key) == binary);
    CHECK_FALSE(kernels::load_program_binary(dir.string(), key + " "));   // another key: no entry
    CHECK(entries(dir).size() == 1);   // the temporary file was renamed, not left beside it

    const fs::path file = kernels::program_cache_file(dir.string(), key);
    const std::string good = slurp(file);
    for (const std::size_t at : {std::size_t(3), good.size() / 2, good.size() - 12, good.size() - 1}) {
        std::string bad = good;
        bad[at] = static_cast<char>(bad[at] ^ 0x20);
        std::ofstream(file, std::ios::binary | std::ios::trunc) << bad;
        INFO("byte " << at << " changed");
        CHECK_FALSE(kernels::load_program_binary(dir.string(), key));
    }
    std::ofstream(file, std::ios::binary | std::ios::trunc) << good.substr(0, good.size() - 1);
    CHECK_FALSE(kernels::load_program_binary(dir.string(), key));
    std::ofstream(file, std::ios::binary | std::ios::trunc) << good << "x";
    CHECK_FALSE(kernels::load_program_binary(dir.string(), key));
}

TEST_CASE("the program cache uses only a private folder, and none when told off", "[cli][opencl][cache]") {
    const fs::path base = clitest::scratch("program_cache_dirs");
    {
        const Env env("CUTLOAD_OPENCL_CACHE_DIR", (base / "a" / "b").string());
        const auto dir = kernels::program_cache_dir();
        REQUIRE(dir);
        struct stat st {};
        REQUIRE(::stat(dir->c_str(), &st) == 0);
        CHECK((st.st_mode & 0777) == 0700);
    }
    fs::create_directories(base / "shared");
    fs::permissions(base / "shared", fs::perms::all);   // 0777: anyone could plant a binary
    {
        const Env env("CUTLOAD_OPENCL_CACHE_DIR", (base / "shared").string());
        CHECK_FALSE(kernels::program_cache_dir());
    }
    // A private folder below one that anyone may change: the checked folder could be renamed
    // away and another put in its place. Sticky (as /tmp) it is fine.
    fs::create_directories(base / "open" / "cache");
    fs::permissions(base / "open" / "cache", fs::perms::owner_all);
    fs::permissions(base / "open", fs::perms::all);
    {
        const Env env("CUTLOAD_OPENCL_CACHE_DIR", (base / "open" / "cache").string());
        CHECK_FALSE(kernels::program_cache_dir());
    }
    fs::permissions(base / "open", fs::perms::all | fs::perms::sticky_bit);
    {
        const Env env("CUTLOAD_OPENCL_CACHE_DIR", (base / "open" / "cache").string());
        CHECK(kernels::program_cache_dir());
    }
    {
        const Env env("CUTLOAD_OPENCL_CACHE_DIR", "off");
        CHECK_FALSE(kernels::program_cache_dir());
    }
}

TEST_CASE("cutload predict on OpenCL gives the same forces from cached programs as from source",
          "[cli][opencl][cache]") {
    const fs::path dir = clitest::scratch("program_cache_predict");
    const fs::path cache = dir / "cache";
    const std::string spec = clitest::source("data/demo_run.json"), log = clitest::source("data/demo_dryrun.csv");
    auto predict = [&](const char* out) {
        const clitest::Result r =
            clitest::run("predict " + log + " --spec " + spec + " --device opencl -q --out " + (dir / out).string());
        INFO(r.output);
        REQUIRE(r.exit_code == 0);
        return slurp(dir / out);
    };
    try {
        kernels::OpenClRuntime::instance();
    } catch (const kernels::OpenClError& e) {
        WARN("no OpenCL device, nothing to cache: " << e.what());
        return;
    }
    const Env env("CUTLOAD_OPENCL_CACHE_DIR", cache.string());
    const std::string from_source = predict("source.csv");
    const std::vector<fs::path> made = entries(cache);
    if (made.empty()) {
        WARN("this OpenCL driver gives no program binaries: nothing was cached");
        return;
    }

    CHECK(predict("cached.csv") == from_source);
    CHECK(entries(cache) == made);   // loaded, nothing new built

    // Every entry damaged in its middle: rebuilt from source, replaced, and the forces unchanged.
    std::vector<std::string> damaged;
    for (const auto& e : made) {
        std::string bad = slurp(e);
        bad[bad.size() / 2] = static_cast<char>(bad[bad.size() / 2] ^ 0x55);
        std::ofstream(e, std::ios::binary | std::ios::trunc) << bad;
        damaged.push_back(bad);
    }
    CHECK(predict("rebuilt.csv") == from_source);
    REQUIRE(entries(cache) == made);
    for (std::size_t i = 0; i < made.size(); ++i) {
        const std::string now = slurp(made[i]);
        CHECK(now != damaged[i]);
    }
    CHECK(predict("cached_again.csv") == from_source);

    const Env off("CUTLOAD_OPENCL_CACHE_DIR", "off");
    fs::remove_all(cache);
    CHECK(predict("off.csv") == from_source);
    CHECK_FALSE(fs::exists(cache));
}
