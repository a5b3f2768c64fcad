#include "aloam_nodelet/core/pose_solver.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <Eigen/Eigenvalues>

namespace aloam
{
namespace
{
constexpr int kTangentSize = 6;  // rotation (3) then translation (3)
using TangentMatrix = Eigen::Matrix<double, kTangentSize, kTangentSize>;
using TangentVector = Eigen::Matrix<double, kTangentSize, 1>;
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

NormalTerms PoseProblem::terms(const double* q, const double* t, double huber_delta) const
{
  // Blocks of a fixed size, so that the sums do not depend on the threads; two blocks per chunk at least
  // (below that a chunk costs more to hand over than it saves).
  constexpr int kMatchesPerBlock = 256;
  const PoseTerms pose(q, t);
  const int n = matchCount();
  const int blocks = (n + kMatchesPerBlock - 1) / kMatchesPerBlock;
  std::vector<NormalTerms> partial(static_cast<std::size_t>(blocks));
  parallelChunks(executor_, blocks, threads_ * kChunksPerThread, 2,
                 [&](int begin, int end, int)
                 {
                   for (int b = begin; b < end; ++b)
                   {
                     accumulateMatches(lines_, planes_, b * kMatchesPerBlock, std::min(n, (b + 1) * kMatchesPerBlock),
                                       pose, huber_delta, partial[b]);
                   }
                 });
  NormalTerms sum;
  for (const NormalTerms& block : partial)
  {
    sum.add(block);
  }
  return sum;
}

namespace
{
// (q, t) moved by a tangent step: q <- [cos|w|, sin|w| w / |w|] * q as the unit-quaternion manifold
// defines it (quaternionPlusJacobian), t <- t + v.
void plus(const double* q, const double* t, const TangentVector& step, double* q_out, double* t_out)
{
  const Eigen::Vector3d w = step.head<3>();
  const double angle = w.norm();
  const Eigen::Map<const Eigen::Quaterniond> from(q);
  Eigen::Map<Eigen::Quaterniond> to(q_out);
  if (angle > 0.0)
  {
    const Eigen::Vector3d v = std::sin(angle) / angle * w;
    to = Eigen::Quaterniond(std::cos(angle), v.x(), v.y(), v.z()) * from;
  }
  else
  {
    to = from;
  }
  for (int i = 0; i < 3; ++i)
  {
    t_out[i] = t[i] + step[3 + i];
  }
}

// (q, t) as the one vector of Ceres's ambient coordinates.
Eigen::Matrix<double, 7, 1> ambient(const double* q, const double* t)
{
  Eigen::Matrix<double, 7, 1> x;
  x << Eigen::Map<const Eigen::Vector4d>(q), Eigen::Map<const Eigen::Vector3d>(t);
  return x;
}

// Ceres's measure of a gradient in the ambient coordinates: max |x - plus(x, -gradient)|.
double gradientMaxNorm(const double* q, const double* t, const TangentVector& gradient)
{
  double q_moved[4], t_moved[3];
  plus(q, t, -gradient, q_moved, t_moved);
  return (ambient(q, t) - ambient(q_moved, t_moved)).lpNorm<Eigen::Infinity>();
}
}  // namespace

void PoseProblem::solve(int max_iterations)
{
  if (matchCount() == 0)
  {
    return;
  }
  // ceres::Solver::Options' defaults for Levenberg-Marquardt.
  constexpr double kInitialRadius = 1e4, kMaxRadius = 1e16, kMinRadius = 1e-32;
  constexpr double kMinRelativeDecrease = 1e-3, kMinDiagonal = 1e-6, kMaxDiagonal = 1e32;
  constexpr double kFunctionTolerance = 1e-6, kGradientTolerance = 1e-10, kParameterTolerance = 1e-8;
  NormalTerms current = terms(q_, t_, huber_delta_);
  if (gradientMaxNorm(q_, t_, current.gradient) <= kGradientTolerance)
  {
    return;
  }
  // Jacobi scaling: columns scaled by 1 / (1 + their norm) at the start, kept for the whole solve.
  const TangentVector scale = (1.0 + current.normal.diagonal().array().sqrt()).inverse().matrix();
  double radius = kInitialRadius, decrease_factor = 2.0, accepted_norm = -1.0;
  const auto reject = [&]
  {
    radius /= decrease_factor;
    decrease_factor *= 2.0;
  };
  for (int iteration = 0; iteration < max_iterations && radius > kMinRadius; ++iteration)
  {
    // The step minimizes |J s + r|^2 + |D s|^2 / radius in the scaled columns, D^2 = diag(J^T J) clamped.
    const TangentMatrix normal = scale.asDiagonal() * current.normal * scale.asDiagonal();
    const TangentVector gradient = scale.asDiagonal() * current.gradient;
    TangentMatrix damped = normal;
    damped.diagonal() += normal.diagonal().cwiseMax(kMinDiagonal).cwiseMin(kMaxDiagonal) / radius;
    const TangentVector scaled_step = -damped.ldlt().solve(gradient);
    const double model_decrease = -(gradient.dot(scaled_step) + 0.5 * scaled_step.dot(normal * scaled_step));
    if (!(model_decrease > 0.0) || !scaled_step.allFinite())
    {
      reject();  // Ceres's invalid step
      continue;
    }
    const TangentVector step = scale.cwiseProduct(scaled_step);
    double q_new[4], t_new[3];
    plus(q_, t_, step, q_new, t_new);
    // Ceres measures the step in the ambient coordinates, against the norm of the point the last accepted
    // step reached (none before the first: its x_norm starts at -1, so the test cannot pass then).
    if (accepted_norm >= 0.0 &&
        (ambient(q_new, t_new) - ambient(q_, t_)).norm() <= kParameterTolerance * (accepted_norm + kParameterTolerance))
    {
      return;
    }
    const NormalTerms candidate = terms(q_new, t_new, huber_delta_);
    const double decrease = std::isfinite(candidate.cost) ? current.cost - candidate.cost : -current.cost;
    if (std::fabs(decrease) <= kFunctionTolerance * current.cost)
    {
      return;  // converged; Ceres keeps the point it had
    }
    const double quality = decrease / model_decrease;
    if (!(quality > kMinRelativeDecrease))
    {
      reject();
      continue;
    }
    std::copy(q_new, q_new + 4, q_);
    std::copy(t_new, t_new + 3, t_);
    current = candidate;
    accepted_norm = ambient(q_, t_).norm();
    radius = std::min(kMaxRadius, radius / std::max(1.0 / 3.0, 1.0 - std::pow(2.0 * quality - 1.0, 3)));
    decrease_factor = 2.0;
    if (gradientMaxNorm(q_, t_, current.gradient) <= kGradientTolerance)
    {
      return;
    }
  }
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
  out.threshold = threshold;
  out.rotation = pose().q.toRotationMatrix();
  if (matchCount() == 0)
  {
    out.degenerate = kTangentSize;
    return out;
  }
  TangentMatrix normal = terms(q_, t_, 0.0).normal;
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

void PoseProblem::remap(const Pose& prior, const Degeneracy& degeneracy, bool soft)
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
  for (int i = 0; i < degeneracy.degenerate; ++i)
  {
    const double keep = soft && degeneracy.threshold > 0.0
                            ? std::clamp(degeneracy.eigenvalues[i] / degeneracy.threshold, 0.0, 1.0)
                            : 0.0;
    const auto v = degeneracy.eigenvectors.col(i);
    step -= (1.0 - keep) * v * (v.transpose() * step);
  }
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
  // The reference of `share`: what the well-constrained directions get on average.
  const double reference = degenerate < 6 ? eigenvalues.tail(6 - degenerate).mean() : eigenvalues[5];
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
    d.share = reference > 0.0 ? std::max(eigenvalues[i], 0.0) / reference : 0.0;
    out.push_back(d);
  }
  return out;
}

std::string describe(const DegenerateDirection& direction)
{
  // Names of motions along or about the sensor's axes (x forward, y left, z up), for a part within about
  // 25 deg of one.
  static const char* const kAlong[3] = { "forward-backward", "left-right", "up-down" };
  static const char* const kAbout[3] = { "roll", "pitch", "yaw" };
  constexpr double kNamedCosine = 0.9;
  const auto part = [&](const char* what, const Eigen::Vector3d& v, const char* const names[3])
  {
    const Eigen::Vector3d u = v.normalized();
    Eigen::Index axis = 0;
    const double cosine = u.cwiseAbs().maxCoeff(&axis);
    char text[128];
    std::snprintf(text, sizeof(text), "%s (%.2f, %.2f, %.2f)%s%s%s", what, u.x(), u.y(), u.z(),
                  cosine >= kNamedCosine ? " (" : "", cosine >= kNamedCosine ? names[axis] : "",
                  cosine >= kNamedCosine ? ")" : "");
    return std::string(text);
  };
  const auto translation = [&] { return part("translation along", direction.translation, kAlong); };
  const auto rotation = [&] { return part("rotation about", direction.rotation, kAbout); };
  const double r = direction.rotation.norm(), t = direction.translation.norm();
  // A part under a quarter of the direction's length is left out.
  constexpr double kMinorShare = 0.25;
  std::string text = t >= r ? translation() : rotation();
  const double minor = std::min(r, t);
  if (minor >= kMinorShare)
  {
    text += " with " + (t >= r ? rotation() : translation());
  }
  if (direction.share >= 0.0)
  {
    char share[96];
    std::snprintf(share, sizeof(share), ": %.*f %% of the constraint of the other directions",
                  direction.share < 0.1 ? 1 : 0, 100.0 * direction.share);
    text += share;
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
