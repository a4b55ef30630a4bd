// The second demo (issue 12): a multi-tool inch program without G20 or G90.1, its dry-run log
// from the generator (tool changes, acceleration-limited corners, client stalls) and the run spec
// draft with a tool table. data/demo2_program.nc and data/demo2_dryrun.csv are the generator's
// output, checked here and regenerated with
//   CUTLOAD_UPDATE_DEMO2=1 build/tests/test_nc "[demo2]"
#include "nc_fixtures.hpp"

#include "motion_io/block_mapping.hpp"

#include <catch2/catch.hpp>

#include <cstdlib>
#include <nlohmann/json.hpp>
#include <set>

using namespace cutload;
using namespace cutload::nctest;

namespace {

std::string demo2_log_text() {
    std::ostringstream csv;
    motion_io::synthesize_nc_dry_run(motion_io::demo2_dry_run_spec(), csv);
    return csv.str();
}

bool updating() {
    const char* update = std::getenv("CUTLOAD_UPDATE_DEMO2");
    return update && std::string(update) == "1";
}

motion_io::MotionModel ingest_text(const std::string& text, const std::string& tag) {
    TempFile f(tag + ".csv", text);
    return motion_io::ingest(f.path(), motion_io::ReadOptions{});
}

// The log without its last column (block): a client that does not read the block number.
std::string without_block_column(const std::string& text) {
    std::string out;
    std::istringstream in(text);
    for (std::string line; std::getline(in, line);) out += line.substr(0, line.rfind(',')) + "\n";
    return out;
}

nlohmann::json demo2_run() { return nlohmann::json::parse(read_text(source_path("data/demo2_run.json"))); }

// The settings a user passes for demo2: --program-units in --arc-centers absolute.
app::ProgramSettings demo2_settings() {
    app::ProgramSettings s;
    s.program_units = motion_io::ProgramUnits::Inch;
    s.arc_centers = motion_io::ArcCenters::Absolute;
    return s;
}

force_model::RunSpec demo2_spec_without_tools() {
    nlohmann::json j = demo2_run();
    j.erase("tools");   // the engine reads the tool table in a later change
    return force_model::parse_run_spec(j);
}

}  // namespace

TEST_CASE("demo2: the bundled program and log are the generator's", "[demo2]") {
    const std::string program_path = source_path("data/demo2_program.nc"), log_path = source_path("data/demo2_dryrun.csv");
    const std::string program = motion_io::demo2_program_text(), log = demo2_log_text();
    if (updating()) {
        std::ofstream(program_path, std::ios::binary) << program;
        std::ofstream(log_path, std::ios::binary) << log;
        WARN("rewrote " << program_path << " and " << log_path);
    }
    CHECK(read_text(program_path) == program);
    CHECK(read_text(log_path) == log);
}

TEST_CASE("demo2: an inch program without G20 and G90.1, three tools, arcs and a pecking cycle", "[demo2]") {
    const std::string text = read_text(source_path("data/demo2_program.nc"));
    std::istringstream lines(text);
    for (std::string line; std::getline(lines, line);)
        for (const std::string& word : motion_io::nc_tokens(line)) {
            CHECK(word != "G20");
            CHECK(word != "G90.1");
        }
    // Read as written (mm, incremental centres) its arcs do not close: the options are needed.
    motion_io::NcReadOptions plain = motion_io::demo2_read_options();
    plain.program_units = motion_io::ProgramUnits::Mm;
    plain.arc_centers = motion_io::ArcCenters::Incremental;
    CHECK_THROWS_AS(motion_io::parse_nc_program(text, "demo2_program.nc", plain), motion_io::NcProgramError);

    const motion_io::NcProgram p = motion_io::parse_nc_program(text, "demo2_program.nc", motion_io::demo2_read_options());
    std::set<int> tools;
    std::size_t changes = 0, arcs = 0, helices = 0, pecks = 0;
    for (const auto& b : p.blocks) {
        if (b.tool >= 0) tools.insert(b.tool);
        changes += b.tool_change;
        if (b.motion == motion_io::NcMotion::ArcCcw) {
            ++arcs;
            helices += b.start_mm[2] != b.end_mm[2];
        }
        pecks += b.cycle == 83 && b.motion == motion_io::NcMotion::Linear;
    }
    CHECK(tools == std::set<int>{1, 2, 3});
    CHECK(changes == 3);
    CHECK(arcs == 22);     // per level: two helix turns, a flat circle, 4 + 4 ring corners
    CHECK(helices == 4);
    CHECK(pecks == 20);    // four holes, 0.5 in from R (0.1 above the top) to the bottom in pecks of 0.1 in
    // in at G54 = machine 250 mm: the first face pass starts 30.48 mm before the stock.
    for (const auto& b : p.blocks)
        if (b.name == "N20") CHECK(b.end_mm[0] == Approx(250 - 1.2 * 25.4));
    // The run spec draft's G54 (minus its setup offset) is the one the program was read with.
    const auto spec = demo2_spec_without_tools();
    for (int a = 0; a < 3; ++a) CHECK(-spec.offset_mm[a] == motion_io::demo2_read_options().work_offsets_mm.at("G54")[a]);
}

TEST_CASE("demo2: the run spec draft's tool table names the program's tools", "[demo2]") {
    const nlohmann::json j = demo2_run();
    REQUIRE(j.contains("tools"));
    std::set<int> numbers;
    for (const auto& t : j["tools"]) {
        numbers.insert(t.at("number").get<int>());
        for (const char* key : {"shape", "diameter_mm", "flutes", "helix_deg", "flute_length_mm", "stickout_mm"}) CHECK(t.contains(key));
        // Milling tools are valid "tool" entries today (the drill's shape is for the later change).
        if (t["shape"] == "drill") continue;
        nlohmann::json one = j;
        one.erase("tools");
        one["tool"] = t;
        one["tool"].erase("number");
        CHECK_NOTHROW(force_model::parse_run_spec(one));
    }
    CHECK(numbers == std::set<int>{1, 2, 3});
}

TEST_CASE("demo2: mapping the log without its block column recovers the logged blocks", "[demo2][mapping]") {
    const std::string text = read_text(source_path("data/demo2_dryrun.csv"));
    const motion_io::MotionModel with_blocks = ingest_text(text, "demo2_blocks");
    const motion_io::MotionModel without = ingest_text(without_block_column(text), "demo2_noblocks");
    REQUIRE(with_blocks.size() == without.size());
    REQUIRE(std::all_of(without.block.begin(), without.block.end(), [](std::int32_t b) { return b < 0; }));
    // The tool column: empty until the first change is done (read as the first tool named, as
    // for blocks), then the program's tools in order.
    REQUIRE(with_blocks.tool.size() == with_blocks.size());
    std::vector<int> order;
    for (std::int32_t t : with_blocks.tool)
        if (order.empty() || order.back() != t) order.push_back(t);
    CHECK(order == std::vector<int>{1, 2, 3});

    const app::ProgramSettings settings = demo2_settings();
    const force_model::RunSpec spec = demo2_spec_without_tools();
    const motion_io::NcProgram prog = motion_io::read_nc_program(
        source_path("data/demo2_program.nc"), app::program_read_options(settings, spec, app::log_start_mm(without)));
    motion_io::BlockMappingOptions mo;
    mo.lead_s = calibrated_lead_s();   // on another program's log from the same machine
    const motion_io::BlockMapping m = motion_io::map_blocks(without, prog, mo);
    const double agreement = motion_io::block_agreement(with_blocks, m.block, m.block_names);
    const auto& q = m.quality;
    WARN(fmt::format("demo2 log ({} samples, {:.1f} s): lead {:.0f} ms; agreement {:.2f}%; matched {:.2f}% of all, {:.2f}% of the "
                     "counted; not counted {:.2f}% ({} at rest, {} away, {} tool change); deviation mean {:.3f} p95 {:.3f} max {:.3f} mm; "
                     "coverage {:.2f}%; {} blocks without samples",
                     without.size(), without.t_s.back() - without.t_s.front(), mo.lead_s * 1e3, 100 * agreement, 100 * q.matched_fraction,
                     100 * q.counted_matched_fraction, 100 * q.excluded_fraction, q.excluded_at_rest, q.excluded_away,
                     q.excluded_tool_change, q.mean_distance_mm, q.p95_distance_mm, q.max_distance_mm, 100 * q.coverage,
                     q.blocks_without_samples.size()));
    CHECK(agreement >= 0.98);
    CHECK(q.excluded_tool_change > 0);
    CHECK(q.counted_matched_fraction > 0.99);
    CHECK(q.matched_fraction < q.counted_matched_fraction);
    CHECK(q.coverage > 0.999);
    CHECK(q.blocks_without_samples.empty());

    // Through the program run the CLI and the service use: accepted, blocks from the mapping.
    motion_io::MotionModel relabelled = without;
    app::ProgramSettings s = settings;
    s.block_lead_ms = mo.lead_s * 1e3;
    const app::ProgramRun run = app::prepare_program_run(
        motion_io::read_nc_program(source_path("data/demo2_program.nc"),
                                   app::program_read_options(s, spec, app::log_start_mm(relabelled))),
        s, relabelled);
    CHECK(run.mapped);
    CHECK(motion_io::block_agreement(with_blocks, relabelled.block, relabelled.block_names) == Approx(agreement));
}
