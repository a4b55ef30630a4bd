#include "engine/tool_plan.hpp"

#include <algorithm>

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

void ToolPlan::append(std::int32_t t) {
    std::int32_t s = 0, number = t;
    if (!one_cutter) {
        if (t < 0) {
            s = unnamed_slot;
            number = unnamed_number;
        } else if (t == last_number_) {
            s = last_slot_;
        } else {
            s = -1;
            for (std::size_t k = 0; k < table_numbers.size(); ++k)
                if (table_numbers[k] == t) s = std::int32_t(k);
            last_number_ = t;
            last_slot_ = s;
        }
    }
    slot.push_back(s);
    this->number.push_back(number);
    if (s < 0) {
        ++unknown_samples;
        if (!std::binary_search(unknown_tools.begin(), unknown_tools.end(), int(t)))
            unknown_tools.insert(std::upper_bound(unknown_tools.begin(), unknown_tools.end(), int(t)), int(t));
    }
}

void ToolPlan::forget_front(std::size_t n) {
    for (auto* v : {&slot, &number}) v->erase(v->begin(), v->begin() + std::ptrdiff_t(std::min(n, v->size())));
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
    plan.one_cutter = false;
    for (const NumberedTool& t : spec.tools) {
        plan.tools.push_back({cutter_from_spec(t.tool), t.number, limits_for(spec.limits, t.limits)});
        plan.table_numbers.push_back(t.number);
    }
    // A sample naming no tool: the run's own tool, else a table of one.
    plan.unnamed_slot = -1;
    if (spec.has_tool) {
        plan.unnamed_slot = std::int32_t(plan.tools.size());
        plan.tools.push_back({cutter_from_spec(spec.tool), -1, spec.limits});
    } else if (spec.tools.size() == 1) {
        plan.unnamed_slot = 0;
        plan.unnamed_number = spec.tools.front().number;
    }

    const std::size_t n = motion.size();
    const bool named = names_tools(motion);
    plan.slot.reserve(n);
    plan.number.reserve(n);
    for (std::size_t i = 0; i < n; ++i) plan.append(named ? motion.tool[i] : -1);
    return plan;
}

}  // namespace cutload::force_model
