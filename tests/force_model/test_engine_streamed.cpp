// A log walked as it is read (StreamingPrediction at the WholeLog pace, docs/force_model.md,
// "Streaming a log"): the motion added in pieces of any size, the walked samples dropped, gives
// predict()'s rows, block summaries, stats, stock checkpoints and final stock on the whole model,
// bit for bit, on both backends; and its checkpoint key, taken piece by piece, is the whole
// model's.
#include "engine_fixtures.hpp"
#include "force_model/stock.hpp"
#include "force_model/streaming.hpp"

using namespace cutload;
using namespace cutload::enginetest;

namespace {

// Samples [first, first + n) of `m` as motion_io::ingest_in_pieces hands them out: the sessions
// that begin inside, as indices into the piece; every block name.
motion_io::MotionModel piece_of(const motion_io::MotionModel& m, std::size_t first, std::size_t n) {
    motion_io::MotionModel p;
    p.step_s = m.step_s;
    p.block_names = m.block_names;
    const auto cut = [&](const auto& v) { return std::decay_t<decltype(v)>(v.begin() + std::ptrdiff_t(first), v.begin() + std::ptrdiff_t(first + n)); };
    p.t_s = cut(m.t_s), p.x_mm = cut(m.x_mm), p.y_mm = cut(m.y_mm), p.z_mm = cut(m.z_mm);
    p.vx_mm_s = cut(m.vx_mm_s), p.vy_mm_s = cut(m.vy_mm_s), p.vz_mm_s = cut(m.vz_mm_s);
    p.spindle_rpm = cut(m.spindle_rpm), p.spindle_angle_deg = cut(m.spindle_angle_deg), p.block = cut(m.block);
    p.tool = m.tool.empty() ? std::vector<std::int32_t>(n, -1) : cut(m.tool);
    for (std::size_t s : m.session_start)
        if (s >= first && s < first + n) p.session_start.push_back(s - first);
    return p;
}

// Two passes along the fixture's bar, long enough for several batches, then a second session
// that starts inside the material elsewhere with its clock set back (tool 7 throughout it).
motion_io::MotionModel two_sessions() {
    motion_io::MotionModel m = legs_motion({-10, 1.5, 7}, {{{50, 1.5, 7}, 3000, "N10"},
                                                         {{50, 1.5, 5}, 3000, "N20"},
                                                         {{-10, 1.5, 5}, 3000, "N30"},
                                                         {{-10, 1.5, 12}, 6000, "N40"}});
    const motion_io::MotionModel b = legs_motion({30, 1.5, 3}, {{{45, 1.5, 3}, 2000, "N50"}});
    m.tool.assign(m.size(), 3);
    const std::size_t first = m.size();
    const double t0_s = m.t_s.back() - 0.5;
    m.session_start.push_back(first);
    const auto names = std::int32_t(m.block_names.size());
    for (std::size_t i = 0; i < b.size(); ++i) {
        m.t_s.push_back(t0_s + b.t_s[i]);
        m.x_mm.push_back(b.x_mm[i]), m.y_mm.push_back(b.y_mm[i]), m.z_mm.push_back(b.z_mm[i]);
        m.vx_mm_s.push_back(b.vx_mm_s[i]), m.vy_mm_s.push_back(b.vy_mm_s[i]), m.vz_mm_s.push_back(b.vz_mm_s[i]);
        m.spindle_rpm.push_back(b.spindle_rpm[i]), m.spindle_angle_deg.push_back(b.spindle_angle_deg[i]);
        m.block.push_back(b.block[i] + names);
        m.tool.push_back(7);
    }
    m.block_names.insert(m.block_names.end(), b.block_names.begin(), b.block_names.end());
    return m;
}

struct Run {
    force_model::Prediction p;
    std::vector<force_model::ForceSample> rows;
    std::vector<TakenCheckpoint> checkpoints;
};

force_model::PredictOptions options(force_model::Device d, Run& run, double checkpoint_every_s) {
    force_model::PredictOptions o;
    o.device = d;
    o.rows_out = [&run](std::span<const force_model::ForceSample> rows) { run.rows.insert(run.rows.end(), rows.begin(), rows.end()); };
    if (checkpoint_every_s > 0) {
        o.checkpoint_every_s = checkpoint_every_s;
        o.checkpoint = [&run](const force_model::StockCheckpoint& at, const force_model::Stock& stock) {
            std::stringstream bytes;
            force_model::save_stock(stock, bytes);
            run.checkpoints.push_back({at, force_model::load_stock(bytes, "checkpoint")});
        };
    }
    return o;
}

Run whole(const motion_io::MotionModel& m, const force_model::RunSpec& spec, force_model::Device d, double every_s) {
    Run run;
    run.p = force_model::predict(m, spec, options(d, run, every_s));
    return run;
}

Run streamed(const motion_io::MotionModel& m, const force_model::RunSpec& spec, force_model::Device d, double every_s,
             std::size_t piece_samples, std::size_t* most_held = nullptr, bool in_parts = false) {
    Run run;
    force_model::StreamingPrediction s(spec, options(d, run, every_s), force_model::StreamPace::WholeLog);
    force_model::StreamOutput out;
    for (std::size_t first = 0; first < m.size(); first += piece_samples) {
        const motion_io::MotionModel piece = piece_of(m, first, std::min(piece_samples, m.size() - first));
        // Each piece added whole, or (as the app walks it) 250 samples at a time.
        for (std::size_t b = 0; b < piece.size(); b += in_parts ? 250 : piece.size()) {
            s.add(piece, b, in_parts ? b + 250 : piece.size());
            s.advance(out);
            if (most_held) *most_held = std::max(*most_held, s.motion().size());
        }
    }
    run.p = s.finish(out);
    CHECK(out.samples.empty());   // they went to rows_out
    return run;
}

void check_same(const Run& a, const Run& b) {
    REQUIRE(a.rows.size() == b.rows.size());
    std::size_t differing = 0;
    for (std::size_t i = 0; i < a.rows.size(); ++i) differing += same_row(a.rows[i], b.rows[i]) ? 0 : 1;
    CHECK(differing == 0);
    REQUIRE(a.p.blocks.size() == b.p.blocks.size());
    for (std::size_t k = 0; k < a.p.blocks.size(); ++k) {
        const force_model::BlockSummary &x = a.p.blocks[k], &y = b.p.blocks[k];
        CHECK(x.block == y.block);
        CHECK(x.tool == y.tool);
        CHECK(x.t_start_s == y.t_start_s);
        CHECK(x.t_end_s == y.t_end_s);
        CHECK(x.peak_force_N == y.peak_force_N);
        CHECK(x.mean_force_N == y.mean_force_N);
        CHECK(x.removed_mm3 == y.removed_mm3);
        CHECK(x.flags.size() == y.flags.size());
    }
    CHECK(a.p.block_names == b.p.block_names);
    CHECK(a.p.stats.steps == b.p.stats.steps);
    CHECK(a.p.stats.cutting_steps == b.p.stats.cutting_steps);
    CHECK(a.p.stats.simulated_s == b.p.stats.simulated_s);
    REQUIRE(a.p.final_stock);
    REQUIRE(b.p.final_stock);
    CHECK(force_model::save_stock_bytes(*a.p.final_stock) == force_model::save_stock_bytes(*b.p.final_stock));
    REQUIRE(a.checkpoints.size() == b.checkpoints.size());
    for (std::size_t k = 0; k < a.checkpoints.size(); ++k) {
        CHECK(a.checkpoints[k].at.sample == b.checkpoints[k].at.sample);
        CHECK(a.checkpoints[k].at.t_s == b.checkpoints[k].at.t_s);
        CHECK(force_model::save_stock_bytes(*a.checkpoints[k].stock) == force_model::save_stock_bytes(*b.checkpoints[k].stock));
    }
}

std::vector<force_model::Device> devices() {
    std::vector<force_model::Device> d{force_model::Device::Cpu};
    if (opencl_available()) d.push_back(force_model::Device::OpenCL);
    else WARN("no OpenCL device: only the scalar twins are checked");
    return d;
}

}  // namespace

TEST_CASE("streamed log: pieces of any size give predict()'s rows, summaries, checkpoints and stock, holding a piece at most",
          "[engine][streamed]") {
    // One session: the passes along the bar and up, every few tenths of a second a checkpoint.
    motion_io::MotionModel m = two_sessions();
    const std::size_t first_session_end = m.session_start[1];
    for (auto* v : {&m.t_s, &m.x_mm, &m.y_mm, &m.z_mm, &m.vx_mm_s, &m.vy_mm_s, &m.vz_mm_s, &m.spindle_rpm, &m.spindle_angle_deg})
        v->resize(first_session_end);
    m.block.resize(first_session_end);
    m.tool.clear();
    m.session_start.resize(1);
    const force_model::RunSpec spec = base_spec(40, 3, 10);
    for (force_model::Device d : devices()) {
        const Run reference = whole(m, spec, d, 0.2);
        // The run cuts the bar's top 5 mm away (600 mm3) in several batches, and is checkpointed
        // where the tool is clear of it.
        double removed_mm3 = 0;
        for (const auto& r : reference.rows) removed_mm3 += r.removed_mm3;
        CHECK(removed_mm3 > 0.8 * 40 * 3 * 5);
        CHECK(reference.p.stats.cutting_steps > reference.rows.size() / 5);
        CHECK(reference.p.stats.steps > 2 * 16384);
        REQUIRE(reference.checkpoints.size() >= 1);
        for (std::size_t piece : {std::size_t(1), std::size_t(97), std::size_t(4096), m.size() + 5}) {
            INFO("piece of " << piece << " samples");
            std::size_t held = 0;
            check_same(reference, streamed(m, spec, d, 0.2, piece, &held));
            // What is not walked yet: the piece and the two samples kept back.
            CHECK(held <= piece + 2);
        }
    }
}

TEST_CASE("streamed log: a second session and a tool change give predict()'s results, and checkpoints there are refused",
          "[engine][streamed]") {
    const motion_io::MotionModel m = two_sessions();
    force_model::RunSpec spec = base_spec(40, 3, 10);
    force_model::NumberedTool t3{3, spec.tool, {}}, t7{7, spec.tool, {}};
    t7.tool.diameter_mm = 6;
    spec.tools = {t3, t7};
    for (force_model::Device d : devices()) {
        const Run reference = whole(m, spec, d, 0);
        CHECK(reference.p.blocks.size() == 5);
        for (std::size_t piece : {std::size_t(333), std::size_t(20000)}) {
            INFO("piece of " << piece << " samples");
            check_same(reference, streamed(m, spec, d, 0, piece));
            check_same(reference, streamed(m, spec, d, 0, piece, nullptr, true));
        }
    }
    // Without rows_out the rows come in the StreamOutputs; the first session's end, inside add(),
    // hands out its rows before any advance(), and they come with the next call.
    for (force_model::Device d : devices()) {
        Run with_rows = whole(m, spec, d, 0);
        force_model::PredictOptions o;
        o.device = d;
        force_model::StreamingPrediction s(spec, o, force_model::StreamPace::WholeLog);
        s.add(m);
        force_model::StreamOutput out;
        s.advance(out);
        CHECK(out.samples.size() > 8192);
        Run held;
        held.rows = std::move(out.samples);
        force_model::StreamOutput rest;
        held.p = s.finish(rest);
        held.rows.insert(held.rows.end(), rest.samples.begin(), rest.samples.end());
        check_same(with_rows, held);
    }
    // predict() writes none for a log of several sessions: a stream asked for them says so.
    Run run;
    force_model::StreamingPrediction s(spec, options(force_model::Device::Cpu, run, 0.2), force_model::StreamPace::WholeLog);
    REQUIRE_THROWS_AS(s.add(m), std::logic_error);
}

TEST_CASE("checkpoint key: taken piece by piece it is the whole model's, and a missing tool channel reads as no tool named",
          "[engine][streamed][checkpoint]") {
    const motion_io::MotionModel m = two_sessions();
    const force_model::RunSpec spec = base_spec(40, 3, 10);
    const std::uint64_t whole_key = force_model::checkpoint_key(m, spec, nullptr);
    for (std::size_t piece : {std::size_t(1), std::size_t(777), m.size()}) {
        force_model::CheckpointKey key;
        for (std::size_t first = 0; first < m.size(); first += piece) key.add(piece_of(m, first, std::min(piece, m.size() - first)), first);
        CHECK(key.key(m.step_s, spec, nullptr) == whole_key);
    }
    // What the walk reads changes the key: a sample's position, its tool, a session's start, the spec.
    motion_io::MotionModel moved = m;
    moved.x_mm[1234] += 1e-9;
    CHECK(force_model::checkpoint_key(moved, spec, nullptr) != whole_key);
    motion_io::MotionModel retooled = m;
    retooled.tool[10] = 4;
    CHECK(force_model::checkpoint_key(retooled, spec, nullptr) != whole_key);
    motion_io::MotionModel resessioned = m;
    resessioned.session_start[1] += 1;
    CHECK(force_model::checkpoint_key(resessioned, spec, nullptr) != whole_key);
    force_model::RunSpec finer = spec;
    finer.resolution.angle_step_deg = 1;
    CHECK(force_model::checkpoint_key(m, finer, nullptr) != whole_key);
    // No tool channel (ingest leaves it empty) and one naming no tool (its pieces) are one motion.
    motion_io::MotionModel untooled = m;
    untooled.tool.clear();
    motion_io::MotionModel unnamed = m;
    unnamed.tool.assign(m.size(), -1);
    CHECK(force_model::checkpoint_key(untooled, spec, nullptr) == force_model::checkpoint_key(unnamed, spec, nullptr));
}
