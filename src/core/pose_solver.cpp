#include "aloam_nodelet/core/pose_solver.h"

#include <algorithm>
#include <cstdio>

#include <Eigen/Eigenvalues>

#include "aloam_nodelet/core/ceres_compat.h"

namespace aloam
{
namespace
{
constexpr int kTangentSize = 6;  // rotation (3) then translation (3)
using TangentMatrix = Eigen::Matrix<double, kTangentSize, kTangentSize>;

// Adds the rows of one match to J^T J, the rotation columns taken into the manifold's tangent.
template <int Rows>
void accumulateNormal(const double* r_jq, const double* r_jt, const Eigen::Matrix<double, 4, 3>& plus,
                      TangentMatrix& normal)
{
  const Eigen::Map<const Eigen::Matrix<double, Rows, 4, Eigen::RowMajor>> jq(r_jq);
  const Eigen::Map<const Eigen::Matrix<double, Rows, 3, Eigen::RowMajor>> jt(r_jt);
  Eigen::Matrix<double, Rows, kTangentSize> j;
  j.template leftCols<3>() = jq * plus;
  j.template rightCols<3>() = jt;
  normal.noalias() += j.transpose() * j;
}
}  // namespace

void MatchSlots::resize(std::size_t line_points, std::size_t plane_points)
{
  lines.resize(line_points);
  line_found.assign(line_points, 0);
  planes.resize(plane_points);
  plane_found.assign(plane_points, 0);
}

PoseProblem::PoseProblem(const Pose& initial, double huber_delta, int threads, Executor* executor)
  : q_{ initial.q.x(), initial.q.y(), initial.q.z(), initial.q.w() }
  , t_{ initial.t.x(), initial.t.y(), initial.t.z() }
  , huber_delta_(huber_delta)
  , threads_(threads)
  , executor_(executor)
{
}

std::pair<int, int> PoseProblem::addMatches(const MatchSlots& slots)
{
  const std::size_t lines_before = lines_.size(), planes_before = planes_.size();
  for (std::size_t i = 0; i < slots.lines.size(); ++i)
  {
    if (slots.line_found[i])
    {
      lines_.push_back(slots.lines[i]);
    }
  }
  for (std::size_t i = 0; i < slots.planes.size(); ++i)
  {
    if (slots.plane_found[i])
    {
      planes_.push_back(slots.planes[i]);
    }
  }
  return { static_cast<int>(lines_.size() - lines_before), static_cast<int>(planes_.size() - planes_before) };
}

void PoseProblem::solve(int max_iterations)
{
  if (matchCount() == 0)
  {
    return;
  }
  ceres::Problem problem;  // owns the cost function and the manifold
  addQuaternionBlock(problem, q_);
  problem.AddParameterBlock(t_, 3);
  problem.AddResidualBlock(new MatchResiduals(lines_, planes_, huber_delta_, threads_, executor_), nullptr, q_, t_);
  // Ceres itself on one thread: MatchResiduals shares the evaluation on the stage's executor (Ceres's own
  // pool measured slower at the sensor rate).
  ceres::Solver::Options options;
  options.linear_solver_type = ceres::DENSE_QR;
  options.max_num_iterations = max_iterations;
  options.minimizer_progress_to_stdout = false;
  options.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
}

Pose PoseProblem::pose() const
{
  return Pose(Eigen::Quaterniond(q_[3], q_[0], q_[1], q_[2]).normalized(), Eigen::Vector3d(t_[0], t_[1], t_[2]));
}

double PoseProblem::constraintStrength(double lever_arm) const
{
  if (matchCount() == 0)
  {
    return 0.0;
  }
  return degeneracy(lever_arm, 0.0).smallest();
}

Degeneracy PoseProblem::degeneracy(double lever_arm, double threshold) const
{
  Degeneracy out;
  out.lever_arm = lever_arm;
  out.rotation = pose().q.toRotationMatrix();
  if (matchCount() == 0)
  {
    out.degenerate = kTangentSize;
    return out;
  }
  const Eigen::Matrix<double, 4, 3> plus = quaternionPlusJacobian(q_);
  TangentMatrix normal = TangentMatrix::Zero();
  const PoseTerms pose(q_, t_);
  double r[3], jq[12], jt[9];
  for (const LineMatch& m : lines_)
  {
    evaluateLine(m, pose, r, jq, jt);
    accumulateNormal<3>(jq, jt, plus, normal);
  }
  for (const PlaneMatch& m : planes_)
  {
    evaluatePlane(m, pose, r, jq, jt);
    accumulateNormal<1>(jq, jt, plus, normal);
  }
  Eigen::Matrix<double, kTangentSize, 1> scale;
  scale << Eigen::Vector3d::Constant(1.0 / lever_arm), Eigen::Vector3d::Ones();
  normal = scale.asDiagonal() * normal * scale.asDiagonal();
  const Eigen::SelfAdjointEigenSolver<TangentMatrix> eig(normal);
  out.eigenvalues = eig.eigenvalues();
  out.eigenvectors = eig.eigenvectors();
  out.degenerate = 0;
  while (out.degenerate < kTangentSize && out.eigenvalues[out.degenerate] < threshold)
  {
    ++out.degenerate;
  }
  return out;
}

int PoseProblem::inliers(double max_residual) const
{
  const PoseTerms pose(q_, t_);
  const double max_sq = max_residual * max_residual;
  double r[3];
  int count = 0;
  for (const LineMatch& m : lines_)
  {
    evaluateLine(m, pose, r, nullptr, nullptr);
    count += r[0] * r[0] + r[1] * r[1] + r[2] * r[2] < max_sq;
  }
  for (const PlaneMatch& m : planes_)
  {
    evaluatePlane(m, pose, r, nullptr, nullptr);
    count += r[0] * r[0] < max_sq;
  }
  return count;
}

void PoseProblem::remap(const Pose& prior, const Degeneracy& degeneracy)
{
  if (degeneracy.degenerate == 0)
  {
    return;
  }
  const Pose current = pose();
  // The step in the scaled tangent at the prior: the manifold applies rotations on the left.
  const Eigen::AngleAxisd step_rotation(current.q * prior.q.conjugate());
  Eigen::Matrix<double, kTangentSize, 1> step;
  step << degeneracy.lever_arm * step_rotation.angle() * step_rotation.axis(), current.t - prior.t;
  const auto weak = degeneracy.eigenvectors.leftCols(degeneracy.degenerate);
  step -= weak * (weak.transpose() * step);
  const Eigen::Vector3d rotation = step.head<3>() / degeneracy.lever_arm;
  const double angle = rotation.norm();
  const Eigen::Quaterniond dq =
      angle > 0.0 ? Eigen::Quaterniond(Eigen::AngleAxisd(angle, rotation / angle)) : Eigen::Quaterniond::Identity();
  const Eigen::Quaterniond q = (dq * prior.q).normalized();
  const Eigen::Vector3d t = prior.t + step.tail<3>();
  q_[0] = q.x();
  q_[1] = q.y();
  q_[2] = q.z();
  q_[3] = q.w();
  t_[0] = t.x();
  t_[1] = t.y();
  t_[2] = t.z();
}

std::vector<DegenerateDirection> Degeneracy::directions() const
{
  std::vector<DegenerateDirection> out;
  // Left-applied rotation and added translation in the parent frame: d (parent) = R d (child).
  const Eigen::Matrix3d to_child = rotation.transpose();
  for (int i = 0; i < degenerate; ++i)
  {
    DegenerateDirection d;
    d.rotation = to_child * eigenvectors.col(i).head<3>();
    d.translation = to_child * eigenvectors.col(i).tail<3>();
    // An eigenvector's sign is arbitrary: make the largest component positive, for stable reports.
    Eigen::Matrix<double, 6, 1> v;
    v << d.rotation, d.translation;
    Eigen::Index largest = 0;
    v.cwiseAbs().maxCoeff(&largest);
    if (v[largest] < 0.0)
    {
      d.rotation = -d.rotation;
      d.translation = -d.translation;
    }
    d.eigenvalue = eigenvalues[i];
    out.push_back(d);
  }
  return out;
}

std::string describe(const DegenerateDirection& direction)
{
  const auto part = [](const char* what, const Eigen::Vector3d& v)
  {
    const Eigen::Vector3d u = v.normalized();
    char text[96];
    std::snprintf(text, sizeof(text), "%s (%.2f, %.2f, %.2f)", what, u.x(), u.y(), u.z());
    return std::string(text);
  };
  const double r = direction.rotation.norm(), t = direction.translation.norm();
  // A part under a quarter of the direction's length is left out.
  constexpr double kMinorShare = 0.25;
  std::string text =
      t >= r ? part("translation along", direction.translation) : part("rotation about", direction.rotation);
  const double minor = std::min(r, t);
  if (minor >= kMinorShare)
  {
    text += " with " +
            (t >= r ? part("rotation about", direction.rotation) : part("translation along", direction.translation));
  }
  return text;
}

std::string describe(const std::vector<DegenerateDirection>& directions)
{
  if (directions.empty())
  {
    return "none";
  }
  std::string text;
  for (const DegenerateDirection& d : directions)
  {
    text += (text.empty() ? "" : "; ") + describe(d);
  }
  return text;
}

}  // namespace aloam
