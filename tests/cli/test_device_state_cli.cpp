// A GPU's path through the engine, run on PoCL: CUTLOAD_OPENCL_DISCRETE=1 makes the CPU device
// behave as one with its own memory (the stock filled on the device or copied up, only the tiles
// removals changed read back), so its transfers are tested where CI runs. Its forces and saved
// stocks must equal those of the usual path byte for byte, from a fresh stock and from a saved one.
#include "cli/run_cli.hpp"
#include "kernels/opencl_runtime.hpp"

#include <fstream>

using namespace cutload;
namespace fs = std::filesystem;

namespace {

std::string slurp(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), {}};
}

}  // namespace

TEST_CASE("the discrete-memory path gives the same forces and stocks as the host-memory path",
          "[cli][opencl][device_state]") {
    try {
        kernels::OpenClRuntime::instance();
    } catch (const kernels::OpenClError& e) {
        WARN("no OpenCL device: " << e.what());
        return;
    }
    const fs::path dir = clitest::scratch("device_state_discrete");
    const std::string spec = clitest::source("data/demo_run.json"), log = clitest::source("data/demo_dryrun.csv");
    auto predict = [&](const std::string& name, const std::string& start) {
        const std::string args = "predict " + log + " --spec " + spec + " --device opencl -q --out " +
                                 (dir / (name + ".csv")).string() + " --save-stock " + (dir / (name + ".stock")).string() +
                                 (start.empty() ? "" : " --start-stock " + (dir / (start + ".stock")).string());
        const clitest::Result r = clitest::run(args);
        INFO(r.output);
        REQUIRE(r.exit_code == 0);
    };
    predict("host", "");
    predict("host_again", "host");
    {
        const clitest::Env discrete("CUTLOAD_OPENCL_DISCRETE", "1");
        predict("discrete", "");
        predict("discrete_again", "host");
    }
    const std::string forces = slurp(dir / "host.csv");
    REQUIRE(forces.size() > 1000000);
    CHECK(slurp(dir / "discrete.csv") == forces);
    CHECK(slurp(dir / "discrete.stock") == slurp(dir / "host.stock"));
    // From a saved stock (copied up, not filled): the second pass re-cuts nothing new.
    CHECK(slurp(dir / "discrete_again.csv") == slurp(dir / "host_again.csv"));
    CHECK(slurp(dir / "discrete_again.stock") == slurp(dir / "host_again.stock"));
    CHECK(slurp(dir / "host_again.stock") == slurp(dir / "host.stock"));
}
