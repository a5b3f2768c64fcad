#include "aloam_nodelet/core/sweep_span.h"

#include <cmath>

#include "aloam_nodelet/core/ceres_compat.h"

namespace aloam
{
namespace
{
// The pose a fraction s of the way through the span (q_s, t_s) -> (q_e, t_e), as SweepSpan::at blends it,
// with the derivatives of its quaternion by the two end quaternions (4 x 4 each, Eigen's x, y, z, w
// order). The blend is normalize(v), v = (1 - s) q_s + s sign q_e, whose derivative by v is
// (I - q q^T) / |v|.
struct BlendTerms
{
  BlendTerms(const double* q_s, const double* t_s, const double* q_e, const double* t_e, double s)
  {
    double sign = 1.0;
    const Eigen::Vector4d v =
        blendCoefficients(Eigen::Map<const Eigen::Vector4d>(q_s), Eigen::Map<const Eigen::Vector4d>(q_e), s, sign);
    const double norm = v.norm();
    const Eigen::Vector4d q = v / norm;
    const Eigen::Matrix4d unit = (Eigen::Matrix4d::Identity() - q * q.transpose()) / norm;
    dq_start = (1.0 - s) * unit;
    dq_end = s * sign * unit;
    for (int i = 0; i < 4; ++i)
    {
      q_at[i] = q[i];
    }
    for (int i = 0; i < 3; ++i)
    {
      t_at[i] = (1.0 - s) * t_s[i] + s * t_e[i];
    }
  }

  double q_at[4], t_at[3];
  Eigen::Matrix4d dq_start, dq_end;
};

void evaluateMatch(const LineMatch& m, const PoseTerms& pose, double* r, double* jq, double* jt)
{
  evaluateLine(m, pose, r, jq, jt);
}
void evaluateMatch(const PlaneMatch& m, const PoseTerms& pose, double* r, double* jq, double* jt)
{
  evaluatePlane(m, pose, r, jq, jt);
}

// One match's residuals (those of the rigid solve, at the blended pose of its point's time) over the
// blocks q_s, t_s, q_e, t_e, with analytic Jacobians: the rigid Jacobians chained through the blend.
template <typename SpanMatch, int Rows>
class SpanCost : public ceres::SizedCostFunction<Rows, 4, 3, 4, 3>
{
public:
  explicit SpanCost(const SpanMatch& m) : m_(m) {}

  bool Evaluate(double const* const* x, double* residuals, double** jacobians) const override
  {
    const double s = m_.s;
    using RowsBy4 = Eigen::Matrix<double, Rows, 4, Eigen::RowMajor>;
    using RowsBy3 = Eigen::Matrix<double, Rows, 3, Eigen::RowMajor>;
    const BlendTerms blend(x[0], x[1], x[2], x[3], s);
    const PoseTerms pose(blend.q_at, blend.t_at);
    RowsBy4 jq;
    RowsBy3 jt;
    evaluateMatch(m_.match, pose, residuals, jacobians != nullptr ? jq.data() : nullptr,
                  jacobians != nullptr ? jt.data() : nullptr);
    if (jacobians == nullptr)
    {
      return true;
    }
    if (jacobians[0] != nullptr)
    {
      Eigen::Map<RowsBy4> jacobian(jacobians[0]);
      jacobian = jq * blend.dq_start;
    }
    if (jacobians[1] != nullptr)
    {
      Eigen::Map<RowsBy3> jacobian(jacobians[1]);
      jacobian = (1.0 - s) * jt;
    }
    if (jacobians[2] != nullptr)
    {
      Eigen::Map<RowsBy4> jacobian(jacobians[2]);
      jacobian = jq * blend.dq_end;
    }
    if (jacobians[3] != nullptr)
    {
      Eigen::Map<RowsBy3> jacobian(jacobians[3]);
      jacobian = s * jt;
    }
    return true;
  }

private:
  SpanMatch m_;
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

ceres::CostFunction* spanCost(const SpanLineMatch& m)
{
  return new SpanCost<SpanLineMatch, 3>(m);
}

ceres::CostFunction* spanCost(const SpanPlaneMatch& m)
{
  return new SpanCost<SpanPlaneMatch, 1>(m);
}

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
    problem.AddResidualBlock(spanCost(m), loss, q_s, t_s, q_e, t_e);
  }
  for (const SpanPlaneMatch& m : planes)
  {
    problem.AddResidualBlock(spanCost(m), loss, q_s, t_s, q_e, t_e);
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
