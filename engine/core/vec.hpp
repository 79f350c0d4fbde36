#pragma once
#include <Eigen/Core>
#include <Eigen/LU>

namespace crowdmpm {
using Vec2 = Eigen::Vector2d;
using Mat2 = Eigen::Matrix2d;
using Vec2i = Eigen::Vector2i;
}  // namespace crowdmpm
