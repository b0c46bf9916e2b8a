#pragma once
// Eigen aliases used across emcalign. The templated forms (`Vec3T<T>`) carry a scalar
// that may be a Ceres Jet: the geometry is written once for both. And kNaN, the one "no
// value" of a double.

#include <limits>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace emcalign {

template <typename T>
using Vec3T = Eigen::Matrix<T, 3, 1>;
template <typename T>
using Mat3T = Eigen::Matrix<T, 3, 3>;

using Vec3 = Vec3T<double>;
using Mat3 = Mat3T<double>;

/// A double with no value (not measured, not computable): a quiet NaN.
inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

}  // namespace emcalign
