#include "aloam_nodelet/core/sweep_span.h"

#include <cmath>

#include "aloam_nodelet/core/ceres_compat.h"

namespace aloam
{
namespace
{
// The point at fraction s of the sweep spanned by (q_s, t_s) and (q_e, t_e).
template <typename T>
Eigen::Matrix<T, 3, 1> placeAt(const T* q_s, const T* t_s, const T* q_e, const T* t_e, double s,
                               const Eigen::Vector3d& p)
{
  const Eigen::Quaternion<T> q = blendRotation(Eigen::Quaternion<T>(Eigen::Map<const Eigen::Quaternion<T>>(q_s)),
                                               Eigen::Quaternion<T>(Eigen::Map<const Eigen::Quaternion<T>>(q_e)), T(s));
  const Eigen::Map<const Eigen::Matrix<T, 3, 1>> a(t_s), b(t_e);
  return q * p.cast<T>() + T(1.0 - s) * a + T(s) * b;
}

struct SpanLineResidual
{
  explicit SpanLineResidual(const SpanLineMatch& m) : m_(m), keep_(freeAxisProjection(m.match)) {}

  template <typename T>
  bool operator()(const T* q_s, const T* t_s, const T* q_e, const T* t_e, T* residual) const
  {
    const Eigen::Matrix<T, 3, 1> x = placeAt(q_s, t_s, q_e, t_e, m_.s, m_.match.point) - m_.match.a.cast<T>();
    Eigen::Map<Eigen::Matrix<T, 3, 1>> r(residual);
    r = keep_.cast<T>() * x.cross(m_.match.direction.cast<T>());
    return true;
  }

  SpanLineMatch m_;
  Eigen::Matrix3d keep_;
};

struct SpanPlaneResidual
{
  explicit SpanPlaneResidual(const SpanPlaneMatch& m) : m_(m) {}

  template <typename T>
  bool operator()(const T* q_s, const T* t_s, const T* q_e, const T* t_e, T* residual) const
  {
    residual[0] = m_.match.normal.cast<T>().dot(placeAt(q_s, t_s, q_e, t_e, m_.s, m_.match.point)) + T(m_.match.d);
    return true;
  }

  SpanPlaneMatch m_;
};

// Holds the start near the prior: the offset of a point lever_arm away (rotation) and the translation,
// times sqrt(weight).
struct StartPrior
{
  StartPrior(const Pose& prior, double weight, double lever_arm)
    : q_inverse_(prior.q.conjugate()), t_(prior.t), scale_(std::sqrt(weight)), lever_arm_(lever_arm)
  {
  }

  template <typename T>
  bool operator()(const T* q_s, const T* t_s, T* residual) const
  {
    const Eigen::Quaternion<T> delta = q_inverse_.cast<T>() * Eigen::Map<const Eigen::Quaternion<T>>(q_s);
    const T sign = delta.w() < T(0) ? T(-1) : T(1);
    for (int i = 0; i < 3; ++i)
    {
      residual[i] = T(scale_ * 2.0 * lever_arm_) * sign * delta.vec()[i];
      residual[3 + i] = T(scale_) * (t_s[i] - T(t_[i]));
    }
    return true;
  }

  Eigen::Quaterniond q_inverse_;
  Eigen::Vector3d t_;
  double scale_, lever_arm_;
};

void unpack(const Pose& pose, double* q, double* t)
{
  const Eigen::Quaterniond unit = pose.q.normalized();
  for (int i = 0; i < 4; ++i)
  {
    q[i] = unit.coeffs()[i];
  }
  for (int i = 0; i < 3; ++i)
  {
    t[i] = pose.t[i];
  }
}
}  // namespace

bool solveSweepSpan(SweepSpan& span, const std::vector<SpanLineMatch>& lines, const std::vector<SpanPlaneMatch>& planes,
                    const Pose& start_prior, const SweepSpanOptions& options)
{
  double q_s[4], t_s[3], q_e[4], t_e[3];
  unpack(span.start, q_s, t_s);
  unpack(span.end, q_e, t_e);
  ceres::Problem problem;
  addQuaternionBlock(problem, q_s);
  addQuaternionBlock(problem, q_e);
  // The problem owns the loss and deletes it once, however many blocks share it.
  ceres::LossFunction* loss = options.huber_delta > 0.0 ? new ceres::HuberLoss(options.huber_delta) : nullptr;
  for (const SpanLineMatch& m : lines)
  {
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<SpanLineResidual, 3, 4, 3, 4, 3>(new SpanLineResidual(m)),
                             loss, q_s, t_s, q_e, t_e);
  }
  for (const SpanPlaneMatch& m : planes)
  {
    problem.AddResidualBlock(
        new ceres::AutoDiffCostFunction<SpanPlaneResidual, 1, 4, 3, 4, 3>(new SpanPlaneResidual(m)), loss, q_s, t_s,
        q_e, t_e);
  }
  problem.AddResidualBlock(new ceres::AutoDiffCostFunction<StartPrior, 6, 4, 3>(
                               new StartPrior(start_prior, options.start_weight, options.lever_arm)),
                           nullptr, q_s, t_s);

  ceres::Solver::Options solver;
  solver.linear_solver_type = ceres::DENSE_QR;
  solver.max_num_iterations = options.max_iterations;
  ceres::Solver::Summary summary;
  ceres::Solve(solver, &problem, &summary);
  const SweepSpan solved{
    Pose(Eigen::Quaterniond(q_s[3], q_s[0], q_s[1], q_s[2]).normalized(), Eigen::Vector3d(t_s[0], t_s[1], t_s[2])),
    Pose(Eigen::Quaterniond(q_e[3], q_e[0], q_e[1], q_e[2]).normalized(), Eigen::Vector3d(t_e[0], t_e[1], t_e[2]))
  };
  if (!summary.IsSolutionUsable() || !solved.start.isFinite() || !solved.end.isFinite())
  {
    return false;
  }
  span = solved;
  return true;
}

}  // namespace aloam
