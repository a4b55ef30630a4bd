// Regenerates the bundled demo dry-run log: cutload_gen_demo_log [OUT.csv] (default: stdout).
// The program's geometry and the machine/client models are in motion_io/synth.cpp.
#include "motion_io/synth.hpp"

#include <cstdio>
#include <fstream>
#include <iostream>

int main(int argc, char** argv) {
    const auto spec = cutload::motion_io::demo_dry_run_spec();
    if (argc > 2) {
        std::fprintf(stderr, "usage: cutload_gen_demo_log [OUT.csv]\n");
        return 2;
    }
    if (argc == 2) {
        std::ofstream out(argv[1], std::ios::binary);
        if (!out) {
            std::fprintf(stderr, "cutload_gen_demo_log: cannot write %s\n", argv[1]);
            return 1;
        }
        const auto rows = cutload::motion_io::synthesize_dry_run(spec, out);
        std::fprintf(stderr, "wrote %zu rows to %s\n", rows, argv[1]);
        return out.good() ? 0 : 1;
    }
    cutload::motion_io::synthesize_dry_run(spec, std::cout);
    return 0;
}
