// Public: the force engine fed motion as it arrives (a live run). Samples of the uniform motion
// grid are added in time order; advance() walks what is new and hands out the force rows that are
// final and the summaries of the blocks that completed. Walking a log's motion this way gives
// the forces of predict() on the whole log: the time steps are the same (whole angle steps of the
// log's own spindle angle), the stock carries over and its removal keeps trailing the tool by the
// stock lag across calls (docs/force_model.md, "Stock lag"). Only the batching differs: a batch
// also ends at each advance(), so its rows come out then (a full batch is over half a second of
// cutting at 10000 rpm and 2 deg steps; waiting for it would be the lag). The removal path keeps
// each batch's last tip, so the chords, and with them sliver contacts at the chord tolerance,
// can differ from predict()'s; block summaries do not depend on the batching (BlockAccumulator).
#pragma once

#include "force_model/force_model.hpp"

#include <memory>
#include <string>
#include <vector>

namespace cutload::force_model {

// How a stream is walked.
enum class StreamPace {
    // A live run: advance() ends the batch, so every row so far comes out then; the motion is kept
    // (motion()).
    Live,
    // A log read in pieces (motion_io::ingest_in_pieces): batches as predict() makes them, so the
    // rows, summaries, checkpoints and final stock are predict()'s on the whole log, bit for bit.
    // advance() walks all but the last two samples added and drops the motion it walked, so memory
    // is bounded by the pieces, the batches and the stock, not by the log's length. Rows go to
    // opt.rows_out when set (else StreamOutput::samples); opt.checkpoint is used, for a log of one
    // session (a second session then is a std::logic_error). opt.window, opt.resume and
    // opt.session_begins are not: a caller that needs them predicts the whole model.
    WholeLog,
};

struct StreamOutput {
    std::vector<ForceSample> samples;        // final rows, in time order, since the last call
    // Blocks that ended since the last call (the motion moved on to another block and no row of it
    // is held back), each summarised over all its rows so far; flags included. A block the
    // program runs again later comes out again, its summary then covering every stretch.
    std::vector<BlockSummary> blocks;
};

class StreamingPrediction {
public:
    // opt.base_stock, opt.device and opt.cancel are used (progress is not); at the WholeLog pace
    // also opt.rows_out, opt.checkpoint, opt.max_rows and opt.keep_final_stock. Throws SpecError
    // for a bad spec, std::runtime_error when the device cannot be set up.
    StreamingPrediction(const RunSpec& spec, const PredictOptions& opt, StreamPace pace = StreamPace::Live);
    ~StreamingPrediction();
    StreamingPrediction(const StreamingPrediction&) = delete;
    StreamingPrediction& operator=(const StreamingPrediction&) = delete;

    // The motion grid: samples of one session in time order; begin_session() before a new one (a
    // gap: nothing is interpolated or swept across it). `block_names` is the full list so far
    // (MotionState::block indexes it; it only grows).
    void begin_session();
    void add(const motion_io::MotionState& s, const std::vector<std::string>& block_names);
    // A piece of the log's motion (motion_io::ingest_in_pieces): its sessions begun where its
    // session_start says, its samples added.
    void add(const motion_io::MotionModel& piece);
    // Its samples [begin, end) alone (a piece walked a part at a time, for progress and cancels).
    void add(const motion_io::MotionModel& piece, std::size_t begin, std::size_t end);

    // Walks the samples added since the last call and appends the final rows and ended blocks to
    // `out` (not cleared). The last row is held back until the next call (a stop's removed volume
    // is booked onto it).
    void advance(StreamOutput& out);
    // Ends the stream: everything left, the last block's summary. The result holds no samples
    // (they went out through advance/finish); blocks are every block's summary over the whole run
    // (a block that ran in several stretches merged, as predict() has it), the final stock and
    // the stats.
    Prediction finish(StreamOutput& out);

    std::size_t motion_samples() const;   // added so far
    // The motion grid added so far (at the Live pace all of it: about 100 bytes a sample; at the
    // WholeLog pace what is not walked yet).
    const motion_io::MotionModel& motion() const;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace cutload::force_model
