// Internal: the engine below the public predict_with (force_model/engine_settings.hpp), for tests
// and benchmarks: a prediction with a cutter built directly from a profile (any shape in
// cutters/shapes.hpp, whether the run spec can name it or not), and the in-process stock.
#pragma once

#include "cutters/cutter.hpp"
#include "force_model/engine_settings.hpp"
#include "force_model/force_model.hpp"
#include "stock.hpp"

namespace cutload::force_model {

// predict_with() with `cutter` in place of the run spec's tool (spec.tool is not read).
Prediction predict_with_cutter(const motion_io::MotionModel& motion, const RunSpec& spec, const Cutter& cutter,
                               const PredictOptions& opt, const EngineSettings& settings,
                               EnginePhases* phases = nullptr);

}  // namespace cutload::force_model
