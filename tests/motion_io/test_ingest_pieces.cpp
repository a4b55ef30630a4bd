// ingest_in_pieces: the motion ingest() builds, handed out piece by piece. Joined again, the pieces
// are the whole model bit for bit (sessions, blocks, tools), whatever their size, on the real
// Okuma log (restart sessions, one too short to keep, hundreds of blocks) and on the multi-tool
// demo (a tool channel).
#include "test_helpers.hpp"

#include <catch2/catch.hpp>

using namespace cutload::motion_io;
using namespace cutload::motion_io::test;

namespace {

struct Joined {
    MotionModel m;
    std::size_t pieces = 0, largest = 0;
    bool in_order = true;   // every piece starts where the one before ended
};

Joined join_pieces(const std::string& path, const ReadOptions& opt, std::size_t piece_samples, IngestReport& report,
                   std::vector<std::string>& names) {
    Joined j;
    report = ingest_in_pieces(
        path, opt, piece_samples,
        [&](const MotionModel& p, std::size_t first) {
            j.in_order = j.in_order && first == j.m.size();
            ++j.pieces;
            j.largest = std::max(j.largest, p.size());
            for (std::size_t s : p.session_start) j.m.session_start.push_back(first + s);
            auto append = [](auto& to, const auto& from) { to.insert(to.end(), from.begin(), from.end()); };
            append(j.m.t_s, p.t_s), append(j.m.x_mm, p.x_mm), append(j.m.y_mm, p.y_mm), append(j.m.z_mm, p.z_mm);
            append(j.m.vx_mm_s, p.vx_mm_s), append(j.m.vy_mm_s, p.vy_mm_s), append(j.m.vz_mm_s, p.vz_mm_s);
            append(j.m.spindle_rpm, p.spindle_rpm), append(j.m.spindle_angle_deg, p.spindle_angle_deg);
            append(j.m.block, p.block), append(j.m.tool, p.tool);
            for (std::size_t k = 0; k < 3; ++k) append(j.m.rot_deg[k], p.rot_deg[k]), append(j.m.rot_vel_deg_s[k], p.rot_vel_deg_s[k]);
            // Every block a sample of the piece names is among the names handed with it.
            for (std::int32_t b : p.block) CHECK(b < std::int32_t(p.block_names.size()));
            j.m.block_names = p.block_names;
            j.m.step_s = p.step_s;
        },
        &names);
    return j;
}

void check_pieces_are_the_model(const std::string& path, const ReadOptions& opt) {
    IngestReport whole_report;
    const MotionModel whole = ingest(path, opt, &whole_report);
    REQUIRE(whole.size() > 1000);
    for (std::size_t piece : {std::size_t(1), std::size_t(1000), std::size_t(65536)}) {
        INFO("pieces of " << piece << " samples");
        IngestReport report;
        std::vector<std::string> names;
        const Joined j = join_pieces(path, opt, piece, report, names);
        CHECK(j.in_order);
        CHECK(j.largest == std::min(piece, whole.size()));
        CHECK(j.pieces == (whole.size() + piece - 1) / piece);
        const MotionModel& m = j.m;
        CHECK(m.step_s == whole.step_s);
        CHECK(m.t_s == whole.t_s);
        CHECK(m.x_mm == whole.x_mm);
        CHECK(m.y_mm == whole.y_mm);
        CHECK(m.z_mm == whole.z_mm);
        CHECK(m.vx_mm_s == whole.vx_mm_s);
        CHECK(m.vy_mm_s == whole.vy_mm_s);
        CHECK(m.vz_mm_s == whole.vz_mm_s);
        CHECK(m.spindle_rpm == whole.spindle_rpm);
        CHECK(m.spindle_angle_deg == whole.spindle_angle_deg);
        CHECK(m.block == whole.block);
        CHECK(m.rot_deg == whole.rot_deg);
        CHECK(m.session_start == whole.session_start);
        // Without a tool channel ingest leaves the tools empty; the pieces say "none named".
        if (whole.tool.empty()) CHECK(m.tool == std::vector<std::int32_t>(whole.size(), -1));
        else CHECK(m.tool == whole.tool);
        CHECK(m.block_names == whole.block_names);
        CHECK(names == whole.block_names);
        CHECK(report.sessions == whole_report.sessions);
        CHECK(report.extent.samples == whole.size());
        CHECK(report.warnings.size() == whole_report.warnings.size());
    }
}

}  // namespace

TEST_CASE("ingest_in_pieces: the real Okuma log's restart sessions and blocks, piece by piece, are ingest()'s",
          "[ingest][pieces][shared]") {
    ReadOptions opt;
    opt.step_ms = 50;
    opt.feed_unit = "mm/min";
    IngestReport report;
    const MotionModel m = ingest(shared_path("data/real/okuma_multus_shdr/okuma.txt"), opt, &report);
    REQUIRE(m.session_start.size() == 3);   // sessions that begin inside pieces, and on their first sample
    CHECK(m.tool.empty());
    check_pieces_are_the_model(shared_path("data/real/okuma_multus_shdr/okuma.txt"), opt);
}

TEST_CASE("ingest_in_pieces: the multi-tool demo's tool channel, piece by piece, is ingest()'s", "[ingest][pieces]") {
    ReadOptions opt;
    const MotionModel m = ingest(source_path("data/demo2_dryrun.csv"), opt);
    REQUIRE(!m.tool.empty());
    CHECK(std::count_if(m.tool.begin(), m.tool.end(), [](std::int32_t t) { return t == 2; }) > 0);
    check_pieces_are_the_model(source_path("data/demo2_dryrun.csv"), opt);
}
