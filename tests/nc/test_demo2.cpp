// The second demo (issue 12): a multi-tool inch program without G20 or G90.1, its dry-run log
// from the generator (tool changes, acceleration-limited corners, client stalls) and its run spec
// with a tool table. data/demo2_program.nc and data/demo2_dryrun.csv are the generator's
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

force_model::RunSpec demo2_spec() { return force_model::parse_run_spec(demo2_run()); }

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
    // The run spec's G54 (minus its setup offset) is the one the program was read with.
    const auto spec = demo2_spec();
    for (int a = 0; a < 3; ++a) CHECK(-spec.offset_mm[a] == motion_io::demo2_read_options().work_offsets_mm.at("G54")[a]);
}

TEST_CASE("demo2: the run spec's tool table has the program's tools, and nothing else", "[demo2]") {
    const force_model::RunSpec spec = demo2_spec();
    CHECK_FALSE(spec.has_tool);
    std::vector<int> numbers;
    for (const auto& t : spec.tools) numbers.push_back(t.number);
    const motion_io::NcProgram p = motion_io::parse_nc_program(read_text(source_path("data/demo2_program.nc")),
                                                               "demo2_program.nc", motion_io::demo2_read_options());
    CHECK(numbers == motion_io::program_tools(p));
    REQUIRE(spec.tools.size() == 3);
    CHECK(spec.tools[0].tool.shape == force_model::ToolShape::Bull);
    CHECK(spec.tools[1].tool.diameter_mm == Approx(0.5 * 25.4));
    CHECK(spec.tools[2].tool.shape == force_model::ToolShape::Drill);
    CHECK(spec.tools[2].tool.diameter_mm == Approx(0.25 * 25.4));
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
    const force_model::RunSpec spec = demo2_spec();
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

namespace {

// The log without its tool column (the second to last): a client that does not read the tool.
std::string without_tool_column(const std::string& text) {
    std::string out;
    std::istringstream in(text);
    for (std::string line; std::getline(in, line);) {
        const std::size_t last = line.rfind(','), tool = line.rfind(',', last - 1);
        out += line.substr(0, tool) + line.substr(last) + "\n";
    }
    return out;
}

// Of the samples where the spindle turns, the fraction whose tool in `a` is the one in `b`.
double tool_agreement_turning(const motion_io::MotionModel& a, const std::vector<std::int32_t>& b) {
    std::size_t n = 0, same = 0;
    for (std::size_t i = 0; i < a.size(); ++i) {
        if (!(std::abs(a.spindle_rpm[i]) > 1)) continue;
        ++n;
        same += a.tool[i] == b[i];
    }
    return n ? double(same) / double(n) : 0.0;
}

}  // namespace

TEST_CASE("demo2: a log without a tool column takes the tools of the program's blocks", "[demo2][tools]") {
    const std::string text = read_text(source_path("data/demo2_dryrun.csv"));
    const motion_io::MotionModel logged = ingest_text(text, "demo2_tools");
    const force_model::RunSpec spec = demo2_spec();
    const app::ProgramSettings settings = demo2_settings();
    auto program = [&](const motion_io::MotionModel& m) {
        return motion_io::read_nc_program(source_path("data/demo2_program.nc"),
                                          app::program_read_options(settings, spec, app::log_start_mm(m)));
    };
    // Block names from the log, tools from the program.
    {
        motion_io::MotionModel m = ingest_text(without_tool_column(text), "demo2_notool");
        REQUIRE(std::none_of(m.tool.begin(), m.tool.end(), [](std::int32_t t) { return t >= 0; }));
        const app::ProgramRun run = app::prepare_program_run(program(m), settings, m);
        CHECK_FALSE(run.mapped);
        CHECK(run.tools_from_program);
        REQUIRE(m.tool.size() == m.size());
        CHECK(std::all_of(m.tool.begin(), m.tool.end(), [](std::int32_t t) { return t >= 1 && t <= 3; }));
        const double agreement = tool_agreement_turning(logged, m.tool);
        WARN(fmt::format("tools from the program's blocks (log block names) agree with the logged tool on {:.2f}% of the "
                         "samples with the spindle turning",
                         100 * agreement));
        CHECK(agreement > 0.99);
    }
    // Neither blocks nor tools in the log: blocks by mapping, tools from the mapped blocks.
    {
        motion_io::MotionModel m = ingest_text(without_block_column(without_tool_column(text)), "demo2_bare");
        app::ProgramSettings s = settings;
        s.block_lead_ms = calibrated_lead_s() * 1e3;
        const app::ProgramRun run = app::prepare_program_run(program(m), s, m);
        CHECK(run.mapped);
        CHECK(run.tools_from_program);
        const double agreement = tool_agreement_turning(logged, m.tool);
        WARN(fmt::format("tools from the mapped blocks agree with the logged tool on {:.2f}% of the samples with the "
                         "spindle turning",
                         100 * agreement));
        CHECK(agreement > 0.99);
    }
    // A log that names its tools keeps them.
    {
        motion_io::MotionModel m = logged;
        const app::ProgramRun run = app::prepare_program_run(program(m), settings, m);
        CHECK_FALSE(run.tools_from_program);
        CHECK(m.tool == logged.tool);
    }
}
