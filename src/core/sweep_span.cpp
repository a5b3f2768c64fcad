#include "aloam_nodelet/core/sweep_span.h"

#include <cmath>

#include "aloam_nodelet/core/ceres_compat.h"

namespace aloam
{
namespace
{
// The point at fraction s of the sweep: rotation blended between q_s and q_e, translation between the
// fixed ends.
template <typename T>
Eigen::Matrix<T, 3, 1> placeAt(const T* q_s, const T* q_e, const Eigen::Vector3d& t_s, const Eigen::Vector3d& t_e,
                               double s, const Eigen::Vector3d& p)
{
  const Eigen::Quaternion<T> q = blendRotation(Eigen::Quaternion<T>(Eigen::Map<const Eigen::Quaternion<T>>(q_s)),
                                               Eigen::Quaternion<T>(Eigen::Map<const Eigen::Quaternion<T>>(q_e)), T(s));
  return q * p.cast<T>() + ((1.0 - s) * t_s + s * t_e).cast<T>();
}

struct SpanLineResidual
{
  SpanLineResidual(const SpanLineMatch& m, const SweepSpan& span)
    : m_(m), keep_(freeAxisProjection(m.match)), t_s_(span.start.t), t_e_(span.end.t)
  {
  }

  template <typename T>
  bool operator()(const T* q_s, const T* q_e, T* residual) const
  {
    const Eigen::Matrix<T, 3, 1> x = placeAt(q_s, q_e, t_s_, t_e_, m_.s, m_.match.point) - m_.match.a.cast<T>();
    Eigen::Map<Eigen::Matrix<T, 3, 1>> r(residual);
    r = keep_.cast<T>() * x.cross(m_.match.direction.cast<T>());
    return true;
  }

  SpanLineMatch m_;
  Eigen::Matrix3d keep_;
  Eigen::Vector3d t_s_, t_e_;
};

struct SpanPlaneResidual
{
  SpanPlaneResidual(const SpanPlaneMatch& m, const SweepSpan& span) : m_(m), t_s_(span.start.t), t_e_(span.end.t) {}

  template <typename T>
  bool operator()(const T* q_s, const T* q_e, T* residual) const
  {
    residual[0] = m_.match.normal.cast<T>().dot(placeAt(q_s, q_e, t_s_, t_e_, m_.s, m_.match.point)) + T(m_.match.d);
    return true;
  }

  SpanPlaneMatch m_;
  Eigen::Vector3d t_s_, t_e_;
};

// Holds the start's rotation near the prior's: the offset of a point lever_arm away, times sqrt(weight).
struct StartPrior
{
  StartPrior(const Eigen::Quaterniond& prior, double weight, double lever_arm)
    : q_inverse_(prior.conjugate()), scale_(std::sqrt(weight) * 2.0 * lever_arm)
  {
  }

  template <typename T>
  bool operator()(const T* q_s, T* residual) const
  {
    const Eigen::Quaternion<T> delta = q_inverse_.cast<T>() * Eigen::Map<const Eigen::Quaternion<T>>(q_s);
    const T sign = delta.w() < T(0) ? T(-1) : T(1);
    for (int i = 0; i < 3; ++i)
    {
      residual[i] = T(scale_) * sign * delta.vec()[i];
    }
    return true;
  }

  Eigen::Quaterniond q_inverse_;
  double scale_;
};

void unpack(const Eigen::Quaterniond& q, double* out)
{
  const Eigen::Quaterniond unit = q.normalized();
  for (int i = 0; i < 4; ++i)
  {
    out[i] = unit.coeffs()[i];
  }
}
}  // namespace

bool solveSweepSpan(SweepSpan& span, const std::vector<SpanLineMatch>& lines, const std::vector<SpanPlaneMatch>& planes,
                    const Eigen::Quaterniond& start_prior, const SweepSpanOptions& options)
{
  double q_s[4], q_e[4];
  unpack(span.start.q, q_s);
  unpack(span.end.q, q_e);
  ceres::Problem problem;
  addQuaternionBlock(problem, q_s);
  addQuaternionBlock(problem, q_e);
  // The problem owns the loss and deletes it once, however many blocks share it.
  ceres::LossFunction* loss = options.huber_delta > 0.0 ? new ceres::HuberLoss(options.huber_delta) : nullptr;
  for (const SpanLineMatch& m : lines)
  {
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<SpanLineResidual, 3, 4, 4>(new SpanLineResidual(m, span)),
                             loss, q_s, q_e);
  }
  for (const SpanPlaneMatch& m : planes)
  {
    problem.AddResidualBlock(
        new ceres::AutoDiffCostFunction<SpanPlaneResidual, 1, 4, 4>(new SpanPlaneResidual(m, span)), loss, q_s, q_e);
  }
  problem.AddResidualBlock(new ceres::AutoDiffCostFunction<StartPrior, 3, 4>(
                               new StartPrior(start_prior, options.start_weight, options.lever_arm)),
                           nullptr, q_s);

  ceres::Solver::Options solver;
  solver.linear_solver_type = ceres::DENSE_QR;
  solver.max_num_iterations = options.max_iterations;
  ceres::Solver::Summary summary;
  ceres::Solve(solver, &problem, &summary);
  const Eigen::Quaterniond start(q_s[3], q_s[0], q_s[1], q_s[2]), end(q_e[3], q_e[0], q_e[1], q_e[2]);
  if (!summary.IsSolutionUsable() || !start.coeffs().allFinite() || !end.coeffs().allFinite())
  {
    return false;
  }
  span.start.q = start.normalized();
  span.end.q = end.normalized();
  return true;
}

}  // namespace aloam
