#include "aloam_nodelet/core/pose_graph.h"

#include <chrono>
#include <stdexcept>

#include "aloam_nodelet/core/ceres_compat.h"

namespace aloam
{
namespace
{
/// Residual of one edge: the translation and rotation by which the measured relative pose differs from
/// the one between the two nodes, in the frame of `from`, whitened by the square-root information.
struct RelativePoseError
{
  RelativePoseError(const Pose& measured, const Eigen::Matrix<double, 6, 6>& sqrt_information)
    : q_measured(measured.q.normalized()), t_measured(measured.t), whiten(sqrt_information)
  {
  }

  template <typename T>
  bool operator()(const T* q_from_raw, const T* t_from_raw, const T* q_to_raw, const T* t_to_raw, T* residual) const
  {
    const Eigen::Map<const Eigen::Quaternion<T>> q_from(q_from_raw);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> t_from(t_from_raw);
    const Eigen::Map<const Eigen::Quaternion<T>> q_to(q_to_raw);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> t_to(t_to_raw);
    const Eigen::Quaternion<T> q_from_inv = q_from.conjugate();
    const Eigen::Matrix<T, 3, 1> t_rel = q_from_inv * (t_to - t_from);
    const Eigen::Quaternion<T> q_rel = q_from_inv * q_to;
    const Eigen::Quaternion<T> q_err = q_measured.cast<T>().conjugate() * q_rel;
    const Eigen::Matrix<T, 3, 1> dt = t_rel - t_measured.cast<T>();
    // 2 * vec(q) is the rotation vector for small errors; the sign keeps the short way round.
    const T sign = q_err.w() < T(0) ? T(-1) : T(1);
    Eigen::Matrix<T, 6, 1> raw;
    raw << dt, T(2) * sign * q_err.vec();
    Eigen::Map<Eigen::Matrix<T, 6, 1>> whitened(residual);
    whitened = whiten.cast<T>() * raw;
    return true;
  }

  Eigen::Quaterniond q_measured;
  Eigen::Vector3d t_measured;
  Eigen::Matrix<double, 6, 6> whiten;
};
}  // namespace

Eigen::Matrix<double, 6, 6> sqrtInformation(double sigma_translation, double sigma_rotation)
{
  Eigen::Matrix<double, 6, 1> inverse;
  inverse << Eigen::Vector3d::Constant(1.0 / sigma_translation), Eigen::Vector3d::Constant(1.0 / sigma_rotation);
  return inverse.asDiagonal();
}

std::size_t PoseGraph::addNode(const Pose& initial)
{
  poses_.push_back(Pose(initial.q.normalized(), initial.t));
  return poses_.size() - 1;
}

bool PoseGraphEdge::isUsable() const
{
  return measured.isFinite() && sqrt_information.allFinite() && sqrt_information.squaredNorm() > 0.0;
}

void PoseGraph::addEdge(const PoseGraphEdge& edge)
{
  if (edge.from >= poses_.size() || edge.to >= poses_.size() || edge.from == edge.to)
  {
    throw std::invalid_argument("pose graph edge between unknown or equal nodes");
  }
  if (!edge.isUsable())
  {
    throw std::invalid_argument("pose graph edge needs a finite, non-zero information and a finite measurement");
  }
  edges_.push_back(edge);
}

double PoseGraph::whitenedError(std::size_t edge) const
{
  const PoseGraphEdge& e = edges_.at(edge);
  const RelativePoseError error(e.measured, e.sqrt_information);
  double r[6];
  error(poses_[e.from].q.coeffs().data(), poses_[e.from].t.data(), poses_[e.to].q.coeffs().data(),
        poses_[e.to].t.data(), r);
  return Eigen::Map<const Eigen::Matrix<double, 6, 1>>(r).norm();
}

bool PoseGraph::solve(std::vector<Pose>& poses, int max_iterations, double loop_loss_scale,
                      PoseGraphSummary& summary) const
{
  ceres::Problem problem;
  for (Pose& p : poses)
  {
    addQuaternionBlock(problem, p.q.coeffs().data());
    problem.AddParameterBlock(p.t.data(), 3);
  }
  for (const PoseGraphEdge& e : edges_)
  {
    if (!e.enabled)
    {
      continue;
    }
    auto* cost = new ceres::AutoDiffCostFunction<RelativePoseError, 6, 4, 3, 4, 3>(
        new RelativePoseError(e.measured, e.sqrt_information));
    ceres::LossFunction* loss = e.loop && loop_loss_scale > 0.0 ? new ceres::CauchyLoss(loop_loss_scale) : nullptr;
    problem.AddResidualBlock(cost, loss, poses[e.from].q.coeffs().data(), poses[e.from].t.data(),
                             poses[e.to].q.coeffs().data(), poses[e.to].t.data());
  }
  problem.SetParameterBlockConstant(poses[0].q.coeffs().data());
  problem.SetParameterBlockConstant(poses[0].t.data());

  ceres::Solver::Options options;
  options.max_num_iterations = max_iterations;
  options.linear_solver_type = ceres::IsSparseLinearAlgebraLibraryTypeAvailable(ceres::SUITE_SPARSE) ||
                                       ceres::IsSparseLinearAlgebraLibraryTypeAvailable(ceres::EIGEN_SPARSE)
                                   ? ceres::SPARSE_NORMAL_CHOLESKY
                                   : ceres::DENSE_QR;
  options.num_threads = 1;
  options.logging_type = ceres::SILENT;
  ceres::Solver::Summary result;
  ceres::Solve(options, &problem, &result);
  summary.iterations += static_cast<int>(result.iterations.size());
  if (summary.initial_cost == 0.0)
  {
    summary.initial_cost = result.initial_cost;
  }
  summary.final_cost = result.final_cost;
  bool usable = result.IsSolutionUsable();
  for (Pose& p : poses)
  {
    usable = usable && p.isFinite();
    p.q.normalize();
  }
  return usable;
}

PoseGraphSummary PoseGraph::optimize(const PoseGraphOptions& options)
{
  PoseGraphSummary summary;
  if (poses_.size() < 2 || edges_.empty())
  {
    return summary;
  }
  const auto start = std::chrono::steady_clock::now();
  std::vector<Pose> poses;
  for (;;)
  {
    poses = poses_;  // each try starts from the graph's poses; a failed solve leaves them as they were
    if (!solve(poses, options.max_iterations, 0.0, summary))
    {
      summary.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
      return summary;
    }
    // The loop that disagrees most with the solution, if any disagrees beyond the bound.
    std::size_t worst = edges_.size(), active = 0;
    double worst_error = options.outlier_error;
    poses_.swap(poses);
    for (std::size_t i = 0; i < edges_.size(); ++i)
    {
      if (!edges_[i].loop || !edges_[i].enabled)
      {
        continue;
      }
      ++active;
      const double error = whitenedError(i);
      if (error > worst_error)
      {
        worst_error = error;
        worst = i;
      }
    }
    poses_.swap(poses);
    if (worst == edges_.size() || active < 2)
    {
      break;
    }
    edges_[worst].enabled = false;
    summary.disabled.push_back(worst);
  }
  if (options.loop_loss_scale > 0.0 && !solve(poses, options.max_iterations, options.loop_loss_scale, summary))
  {
    summary.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    return summary;
  }
  poses_ = poses;
  summary.solved = true;
  summary.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return summary;
}

void PoseGraph::clear()
{
  poses_.clear();
  edges_.clear();
}

}  // namespace aloam
