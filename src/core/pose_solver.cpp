#include "aloam_nodelet/core/pose_solver.h"

#include <Eigen/Eigenvalues>

#include "aloam_nodelet/core/ceres_compat.h"
#include "aloam_nodelet/core/lidar_factors.h"

namespace aloam
{
namespace
{
constexpr int kTangentSize = 6;  // rotation (3) then translation (3)

ceres::Problem::Options problemOptions()
{
  ceres::Problem::Options options;
  options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  return options;
}
}  // namespace

void MatchSlots::resize(std::size_t line_points, std::size_t plane_points)
{
  lines.resize(line_points);
  line_found.assign(line_points, 0);
  planes.resize(plane_points);
  plane_found.assign(plane_points, 0);
}

std::pair<int, int> PoseProblem::addMatches(const MatchSlots& slots)
{
  int lines = 0, planes = 0;
  for (std::size_t i = 0; i < slots.lines.size(); ++i)
  {
    if (slots.line_found[i])
    {
      const LineMatch& m = slots.lines[i];
      addResidual(PointToLineResidual::create(m.point, m.a, m.direction));
      ++lines;
    }
  }
  for (std::size_t i = 0; i < slots.planes.size(); ++i)
  {
    if (slots.plane_found[i])
    {
      const PlaneMatch& m = slots.planes[i];
      addResidual(PointToPlaneResidual::create(m.point, m.normal, m.d));
      ++planes;
    }
  }
  return { lines, planes };
}

PoseProblem::PoseProblem(const Pose& initial, double huber_delta)
  : q_{ initial.q.x(), initial.q.y(), initial.q.z(), initial.q.w() }
  , t_{ initial.t.x(), initial.t.y(), initial.t.z() }
  , loss_(std::make_unique<ceres::HuberLoss>(huber_delta))
  , problem_(problemOptions())
{
  addQuaternionBlock(problem_, q_);
  problem_.AddParameterBlock(t_, 3);
}

void PoseProblem::solve(int max_iterations)
{
  // One thread: Ceres starts its thread pool per problem, and at the sensor rate (idle gaps between
  // sweeps) a second thread measured slower, not faster (KITTI at 10 Hz: 45.8 vs 42.6 ms to the pose).
  ceres::Solver::Options options;
  options.linear_solver_type = ceres::DENSE_QR;
  options.max_num_iterations = max_iterations;
  options.minimizer_progress_to_stdout = false;
  options.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem_, &summary);
}

Pose PoseProblem::pose() const
{
  return Pose(Eigen::Quaterniond(q_[3], q_[0], q_[1], q_[2]).normalized(), Eigen::Vector3d(t_[0], t_[1], t_[2]));
}

double PoseProblem::constraintStrength(double lever_arm)
{
  if (problem_.NumResidualBlocks() == 0)
  {
    return 0.0;
  }
  ceres::Problem::EvaluateOptions options;
  options.parameter_blocks = { q_, t_ };
  options.apply_loss_function = false;
  ceres::CRSMatrix jacobian;
  if (!problem_.Evaluate(options, nullptr, nullptr, nullptr, &jacobian) || jacobian.num_cols != kTangentSize)
  {
    return 0.0;
  }
  // J^T J from the compressed rows; the tangent of the quaternion manifold comes first.
  Eigen::Matrix<double, kTangentSize, kTangentSize> normal = Eigen::Matrix<double, kTangentSize, kTangentSize>::Zero();
  for (int row = 0; row < jacobian.num_rows; ++row)
  {
    Eigen::Matrix<double, kTangentSize, 1> j = Eigen::Matrix<double, kTangentSize, 1>::Zero();
    for (int k = jacobian.rows[row]; k < jacobian.rows[row + 1]; ++k)
    {
      j[jacobian.cols[k]] = jacobian.values[k];
    }
    normal += j * j.transpose();
  }
  Eigen::Matrix<double, kTangentSize, 1> scale;
  scale << Eigen::Vector3d::Constant(1.0 / lever_arm), Eigen::Vector3d::Ones();
  normal = scale.asDiagonal() * normal * scale.asDiagonal();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, kTangentSize, kTangentSize>> eig(normal);
  return eig.eigenvalues()[0];
}

}  // namespace aloam
