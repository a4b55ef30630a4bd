// Regenerates the bundled demo data (see data/README.md):
//   cutload_gen_demo_log [OUT.csv]                   the first demo's log (data/demo_dryrun.csv)
//   cutload_gen_demo_log --demo2 [OUT.csv]           the second demo's log (data/demo2_dryrun.csv)
//   cutload_gen_demo_log --demo2 --program [OUT.nc]  its program (data/demo2_program.nc)
//   cutload_gen_demo_log --demo3 [OUT.csv]           the five-axis demo's log (data/demo3_dryrun.csv)
//   cutload_gen_demo_log --demo3 --program [OUT.nc]  its program (data/demo3_program.nc)
//   cutload_gen_demo_log --demo4 [OUT.csv]           the 3+2 demo's log (data/demo4_dryrun.csv)
//   cutload_gen_demo_log --demo4 --program [OUT.nc]  its program (data/demo4_program.nc)
// Without OUT, to stdout. The programs' geometry and the machine/client models are in
// motion_io/synth.cpp.
#include "motion_io/synth.hpp"

#include <cstdio>
#include <fstream>
#include <iostream>
#include <string>

int main(int argc, char** argv) {
    bool demo2 = false, demo3 = false, demo4 = false, program = false;
    std::string out_path;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        if (a == "--demo2") demo2 = true;
        else if (a == "--demo3") demo3 = true;
        else if (a == "--demo4") demo4 = true;
        else if (a == "--program") program = true;
        else if (out_path.empty() && !a.empty() && a[0] != '-') out_path = a;
        else {
            std::fprintf(stderr, "usage: cutload_gen_demo_log [--demo2|--demo3|--demo4 [--program]] [OUT]\n");
            return 2;
        }
    }
    if (int(demo2) + int(demo3) + int(demo4) > 1) {
        std::fprintf(stderr, "cutload_gen_demo_log: one of --demo2, --demo3, --demo4\n");
        return 2;
    }
    if (program && !demo2 && !demo3 && !demo4) {
        std::fprintf(stderr, "cutload_gen_demo_log: --program needs --demo2, --demo3 or --demo4 (the first demo's program is written by its test)\n");
        return 2;
    }
    std::ofstream file;
    if (!out_path.empty()) {
        file.open(out_path, std::ios::binary);
        if (!file) {
            std::fprintf(stderr, "cutload_gen_demo_log: cannot write %s\n", out_path.c_str());
            return 1;
        }
    }
    std::ostream& out = out_path.empty() ? std::cout : file;
    try {
        if (program) {
            out << (demo4   ? cutload::motion_io::demo4_program_text()
                    : demo3 ? cutload::motion_io::demo3_program_text()
                            : cutload::motion_io::demo2_program_text());
        } else {
            const std::size_t rows = demo4   ? cutload::motion_io::synthesize_nc_dry_run(cutload::motion_io::demo4_dry_run_spec(), out)
                                     : demo3 ? cutload::motion_io::synthesize_nc_dry_run(cutload::motion_io::demo3_dry_run_spec(), out)
                                     : demo2 ? cutload::motion_io::synthesize_nc_dry_run(cutload::motion_io::demo2_dry_run_spec(), out)
                                             : cutload::motion_io::synthesize_dry_run(cutload::motion_io::demo_dry_run_spec(), out);
            if (!out_path.empty()) std::fprintf(stderr, "wrote %zu rows to %s\n", rows, out_path.c_str());
        }
    } catch (const std::exception& e) {
        std::fprintf(stderr, "cutload_gen_demo_log: %s\n", e.what());
        return 1;
    }
    out.flush();
    return out.good() ? 0 : 1;
}
