// A sweep as a motion rather than one pose: a start and an end pose, with the sensor moving between them at
// constant velocity (CT-ICP's model). Mapping solves both for sweeps in which the motion changed, whose
// deskewing with one motion was wrong.
#pragma once

#include <vector>

#include <Eigen/Geometry>

#include "aloam_nodelet/core/lidar_factors.h"
#include "aloam_nodelet/core/pose.h"

namespace aloam
{
/// The unnormalized blend of two quaternions' coefficients (x, y, z, w): (1 - s) a + s sign b, where `sign`
/// (returned too) brings b onto a's hemisphere.
inline Eigen::Vector4d blendCoefficients(const Eigen::Vector4d& a, const Eigen::Vector4d& b, double s, double& sign)
{
  sign = a.dot(b) < 0.0 ? -1.0 : 1.0;
  return (1.0 - s) * a + s * sign * b;
}

/// The rotation a fraction `s` of the way from `a` to `b`: the normalized blend (nlerp) of the two unit
/// quaternions on the same hemisphere, within a few thousandths of a degree of slerp over a sweep's turn.
/// (spanCost differentiates the same blend.)
inline Eigen::Quaterniond blendRotation(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b, double s)
{
  double sign = 1.0;
  return Eigen::Quaterniond(blendCoefficients(a.coeffs(), b.coeffs(), s, sign).normalized());
}

/// The sensor's poses at the start and the end of a sweep (map <- sensor).
struct SweepSpan
{
  Pose start, end;

  /// The pose at fraction `s` of the sweep (0: start, 1: end).
  Pose at(double s) const { return Pose(blendRotation(start.q, end.q, s), (1.0 - s) * start.t + s * end.t); }
};

/// A match of a point taken at fraction `s` of the sweep; `point` in the sensor frame of that instant.
struct SpanLineMatch
{
  LineMatch match;
  double s = 1.0;
};
struct SpanPlaneMatch
{
  PlaneMatch match;
  double s = 1.0;
};

struct SweepSpanOptions
{
  int max_iterations = 4;
  double huber_delta = 0.1;  ///< Huber loss scale of the matches (m); <= 0: none
  /// The start is held to `start_prior` (where the previous sweep ended) as strongly as this many point
  /// matches would hold it; rotations count as the motion of a point lever_arm away.
  double start_weight = 3.0;
  double lever_arm = 10.0;
};

/// The residuals of one match under a span (those of the rigid solve, evaluateLine / evaluatePlane, at the
/// blended pose of the match's time) as a Ceres cost function over the parameter blocks q_start, t_start,
/// q_end, t_end (quaternions in Eigen's x, y, z, w order), with analytic Jacobians. The caller owns it.
ceres::CostFunction* spanCost(const SpanLineMatch& m);
ceres::CostFunction* spanCost(const SpanPlaneMatch& m);

/// Solves the start and end poses of `span` under the matches and the start's prior. No handling of weak
/// directions: along one the span wanders (mapping spans only strongly constrained sweeps). Ceres, on
/// the calling thread so that the result does not depend on threads.
/// Returns false when the solve failed (span unchanged).
bool solveSweepSpan(SweepSpan& span, const std::vector<SpanLineMatch>& lines, const std::vector<SpanPlaneMatch>& planes,
                    const Pose& start_prior, const SweepSpanOptions& options);

}  // namespace aloam
