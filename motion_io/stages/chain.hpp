// Internal: a chain of ingest stages from the reader's records to a grid sink.
//
// Stages are kept in order; bind() checks that every kind a stage accepts is emitted upstream
// and every kind emitted reaches a stage (or the sink) that accepts it, then routes each
// stage's output of each kind straight to that consumer. Records pushed into the chain (by a
// reader or a live source) flow through the stages; grid samples come out at the sink as soon
// as they are final; finish() ends the stream and flushes everything still held.
#pragma once

#include "stages/stage.hpp"

#include <memory>
#include <string>
#include <string_view>
#include <vector>

namespace cutload::motion_io::detail {

class StageChain final : public RecordSink {
public:
    explicit StageChain(GridSink& sink);
    ~StageChain() override;

    // Building: stages in order, then bind(). Inserting or removing by name re-binds at once
    // and throws std::logic_error (naming the stage and the kind) if the chain no longer fits.
    void append(std::unique_ptr<Stage> stage);
    void insert_before(std::string_view name, std::unique_ptr<Stage> stage);
    void insert_after(std::string_view name, std::unique_ptr<Stage> stage);
    std::unique_ptr<Stage> remove(std::string_view name);
    void bind();

    Stage* find(std::string_view name) const;
    template <class T>
    T* find_as(std::string_view name) const {
        return dynamic_cast<T*>(find(name));
    }
    std::vector<std::string> names() const;

    // The reader's side.
    void push(const Record& r) override { entry_->record(r); }
    void finish() override { entry_->finish(); }

    // Counts of every stage (and the sessions seen) added to the report.
    void fill_report(IngestReport& report) const;

private:
    class Terminal;
    std::size_t index_of(std::string_view name) const;
    std::vector<std::unique_ptr<Stage>> stages_;
    std::unique_ptr<Terminal> terminal_;
    Stage* entry_ = nullptr;
};

}  // namespace cutload::motion_io::detail
