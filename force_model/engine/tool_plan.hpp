// Internal: which cutter cuts each sample of a run. With no tool table, the run's one tool cuts
// everything (as before tool tables). With one, a sample's tool is the table entry of its T number
// (the motion's tool channel: the log's own, or the NC program's tools of the mapped blocks, put
// there by app/program_run); a sample that names no tool takes the run's `tool`, or the table's
// only entry. A T number the table does not have is not guessed: the sample has no cutter (slot -1),
// gets no forces and removes nothing, and its block is flagged unknown_tool.
#pragma once

#include "cutters/cutter.hpp"
#include "force_model/force_model.hpp"

#include <cstdint>
#include <vector>

namespace cutload::force_model {

struct PlannedTool {
    Cutter cutter;
    std::int32_t number = -1;   // T number; -1: the run's single tool
    Limits limits;              // the run's, with the tool's own overrides
};

struct ToolPlan {
    std::vector<PlannedTool> tools;      // the engine's cutter slots
    // Per sample: the slot (-1: unknown tool) and the T number written on its rows (-1: none
    // named). Empty: slot 0 and number -1 throughout.
    std::vector<std::int32_t> slot, number;
    std::size_t unknown_samples = 0;
    std::vector<int> unknown_tools;      // sorted; -1: samples naming no tool

    std::int32_t slot_at(std::size_t i) const { return slot.empty() ? 0 : slot[i]; }
    std::int32_t number_at(std::size_t i) const { return number.empty() ? -1 : number[i]; }
    // The slot of the first sample that has a cutter (0 when none has).
    std::int32_t first_slot() const;

    // Appends the next sample's slot and number from its T number (-1: it names none). How
    // plan_tools() fills the per-sample lists, and how a live run's plan grows with its motion.
    void append(std::int32_t t);
    // The first n samples' entries are gone (a motion that drops what it walked, Engine::forget_samples).
    void forget_front(std::size_t n);

    // How append() maps T numbers (set by plan_tools / single_cutter_plan).
    bool one_cutter = true;                        // slot 0 throughout; rows carry the sample's T number
    std::int32_t unnamed_slot = 0, unnamed_number = -1;   // a sample naming no tool
    std::vector<std::int32_t> table_numbers;       // T number of each table slot

private:
    std::int32_t last_number_ = -2, last_slot_ = -1;   // runs of one tool are long: the last lookup
};

// From the run spec (its tool, its table) and the motion's tool channel.
ToolPlan plan_tools(const motion_io::MotionModel& motion, const RunSpec& spec);

// One cutter for every sample (predict_with_cutter); rows carry the motion's T numbers.
ToolPlan single_cutter_plan(const motion_io::MotionModel& motion, const Cutter& cutter, const Limits& limits);

}  // namespace cutload::force_model
