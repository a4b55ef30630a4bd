#include "engine/tool_plan.hpp"

#include <algorithm>
#include <set>

namespace cutload::force_model {

namespace {

bool names_tools(const motion_io::MotionModel& m) {
    return m.tool.size() == m.size() && std::any_of(m.tool.begin(), m.tool.end(), [](std::int32_t t) { return t >= 0; });
}

}  // namespace

std::int32_t ToolPlan::first_slot() const {
    for (std::int32_t s : slot)
        if (s >= 0) return s;
    return 0;
}

ToolPlan single_cutter_plan(const motion_io::MotionModel& motion, const Cutter& cutter, const Limits& limits) {
    ToolPlan plan;
    plan.tools.push_back({cutter, -1, limits});
    if (names_tools(motion)) plan.number = motion.tool;
    return plan;
}

ToolPlan plan_tools(const motion_io::MotionModel& motion, const RunSpec& spec) {
    if (spec.tools.empty()) return single_cutter_plan(motion, cutter_from_spec(spec.tool), spec.limits);

    ToolPlan plan;
    for (const NumberedTool& t : spec.tools)
        plan.tools.push_back({cutter_from_spec(t.tool), t.number, limits_for(spec.limits, t.limits)});
    // A sample naming no tool: the run's own tool, else a table of one.
    std::int32_t unnamed_slot = -1, unnamed_number = -1;
    if (spec.has_tool) {
        unnamed_slot = std::int32_t(plan.tools.size());
        plan.tools.push_back({cutter_from_spec(spec.tool), -1, spec.limits});
    } else if (spec.tools.size() == 1) {
        unnamed_slot = 0;
        unnamed_number = spec.tools.front().number;
    }

    const std::size_t n = motion.size();
    const bool named = names_tools(motion);
    plan.slot.resize(n);
    plan.number.resize(n);
    std::set<int> unknown;
    // Runs of one tool are long: remember the last lookup.
    std::int32_t last_number = -2, last_slot = -1;
    for (std::size_t i = 0; i < n; ++i) {
        const std::int32_t t = named ? motion.tool[i] : -1;
        std::int32_t slot = -1, number = t;
        if (t < 0) {
            slot = unnamed_slot;
            number = unnamed_number;
        } else if (t == last_number) {
            slot = last_slot;
        } else {
            for (std::size_t k = 0; k < spec.tools.size(); ++k)
                if (spec.tools[k].number == t) slot = std::int32_t(k);
            last_number = t;
            last_slot = slot;
        }
        plan.slot[i] = slot;
        plan.number[i] = number;
        if (slot < 0) {
            ++plan.unknown_samples;
            unknown.insert(t);
        }
    }
    plan.unknown_tools.assign(unknown.begin(), unknown.end());
    return plan;
}

}  // namespace cutload::force_model
