// Internal: predict_turning's walk (force_model.hpp): a motion whose tool turns while it cuts,
// on the tri-dexel stock with the pose engine (engine/pose_engine.hpp). It walks the motion as
// the Z-map engine's driver does: per interval air (one row per sample), a stopped spindle (one
// row), or angle steps (motion_walk's IntervalSteps: the tip, its velocity and the spindle angle),
// each step given the orientation interpolated between the samples' poses and the turn of the
// tool frame per tooth; rows and block summaries as the driver makes them (engine/rows.hpp).
#pragma once

#include "engine/tool_plan.hpp"
#include "force_model/force_model.hpp"

#include <functional>
#include <span>

namespace cutload::force_model {

// `check_rows` is called on every piece of rows before it leaves (no NaN may). Throws SpecError for
// what the pose engine cannot take yet (several cutters, a base stock, a tool whose cutting part
// is not convex) and std::invalid_argument for poses that do not match the motion.
Prediction run_turning(const motion_io::MotionModel& motion, const ToolPoses& poses, const RunSpec& spec,
                       const ToolPlan& plan, const PredictOptions& opt,
                       const std::function<void(std::span<const ForceSample>)>& check_rows);

}  // namespace cutload::force_model
