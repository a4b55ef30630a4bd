// Internal: points and vectors of the walk, in millimetres (stock coordinates) or mm/s.
#pragma once

#include <cmath>

namespace cutload::force_model {

struct Vec3 {
    double x = 0, y = 0, z = 0;
};

// std::hypot's overflow care costs more than the rest of a time step; these are millimetres.
inline double norm3(double x, double y, double z) { return std::sqrt(x * x + y * y + z * z); }
inline double distance_mm(const Vec3& a, const Vec3& b) { return norm3(a.x - b.x, a.y - b.y, a.z - b.z); }

}  // namespace cutload::force_model
