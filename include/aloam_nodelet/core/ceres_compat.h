// The one place that knows which Ceres API is installed: manifolds (Ceres >= 2.1) or local
// parameterizations (Ceres 1.14 on Ubuntu 20.04 / ROS Noetic).
#pragma once

#include <ceres/ceres.h>
#include <ceres/version.h>

#if (CERES_VERSION_MAJOR > 2) || (CERES_VERSION_MAJOR == 2 && CERES_VERSION_MINOR >= 1)
#define ALOAM_CERES_HAS_MANIFOLDS 1
#else
#define ALOAM_CERES_HAS_MANIFOLDS 0
#endif

namespace aloam
{
/// Adds a 4-vector in Eigen's (x, y, z, w) memory order as a unit quaternion parameter block.
inline void addQuaternionBlock(ceres::Problem& problem, double* q)
{
#if ALOAM_CERES_HAS_MANIFOLDS
  problem.AddParameterBlock(q, 4, new ceres::EigenQuaternionManifold);
#else
  problem.AddParameterBlock(q, 4, new ceres::EigenQuaternionParameterization);
#endif
}

}  // namespace aloam
