// PoseProblem: the solve recovers a known pose, the constraint strength is the one Ceres's own Jacobian
// gives, and threads do not change the result.
#include <random>
#include <vector>

#include <Eigen/Eigenvalues>
#include <gtest/gtest.h>

#include "aloam_nodelet/core/ceres_compat.h"
#include "aloam_nodelet/core/pose_solver.h"

namespace aloam
{
namespace
{
// Matches that the pose `truth` satisfies exactly: planes and lines through the transformed points, in
// every direction; `outliers` of them displaced by 2 m.
MatchSlots exactMatches(const Pose& truth, int lines, int planes, double outlier_fraction, std::mt19937& rng)
{
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  const auto random3 = [&] { return Eigen::Vector3d(normal(rng), normal(rng), normal(rng)); };
  MatchSlots slots;
  slots.resize(lines, planes);
  for (int i = 0; i < lines; ++i)
  {
    const Eigen::Vector3d p = 15.0 * random3();
    const Eigen::Vector3d x = truth.q * p + truth.t;
    const Eigen::Vector3d u = random3().normalized();
    Eigen::Vector3d a = x + 2.0 * normal(rng) * u;
    if (uniform(rng) < outlier_fraction)
    {
      a += 2.0 * u.cross(random3()).normalized();
    }
    slots.lines[i] = LineMatch{ p, a, u };
    slots.line_found[i] = 1;
  }
  for (int i = 0; i < planes; ++i)
  {
    const Eigen::Vector3d p = 15.0 * random3();
    const Eigen::Vector3d x = truth.q * p + truth.t;
    const Eigen::Vector3d n = random3().normalized();
    double d = -n.dot(x);
    if (uniform(rng) < outlier_fraction)
    {
      d += 2.0;
    }
    slots.planes[i] = PlaneMatch{ p, n, d };
    slots.plane_found[i] = 1;
  }
  return slots;
}

Pose perturbed(const Pose& pose, double angle, double shift)
{
  const Eigen::Quaterniond dq(Eigen::AngleAxisd(angle, Eigen::Vector3d(1.0, 2.0, -1.0).normalized()));
  return Pose(dq * pose.q, pose.t + Eigen::Vector3d(shift, -shift, 0.5 * shift));
}

double angleBetween(const Pose& a, const Pose& b)
{
  return a.q.angularDistance(b.q);
}

TEST(PoseSolver, RecoversAKnownPose)
{
  std::mt19937 rng(1);
  const Pose truth(Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitZ())),
                   Eigen::Vector3d(3.0, -1.0, 0.2));
  {
    PoseProblem problem(perturbed(truth, 0.05, 0.3), 0.1);
    const auto [lines, planes] = problem.addMatches(exactMatches(truth, 150, 400, 0.0, rng));
    EXPECT_EQ(lines, 150);
    EXPECT_EQ(planes, 400);
    problem.solve(20);
    EXPECT_LT((problem.pose().t - truth.t).norm(), 1e-6);
    EXPECT_LT(angleBetween(problem.pose(), truth), 1e-7);
  }
  {
    // A tenth of the matches 2 m off: the robust loss bounds their pull.
    PoseProblem problem(perturbed(truth, 0.05, 0.3), 0.1);
    problem.addMatches(exactMatches(truth, 150, 400, 0.1, rng));
    problem.solve(20);
    EXPECT_LT((problem.pose().t - truth.t).norm(), 0.02);
    EXPECT_LT(angleBetween(problem.pose(), truth), 2e-3);
    PoseProblem plain(perturbed(truth, 0.05, 0.3), 1e6);  // without it, for comparison
    plain.addMatches(exactMatches(truth, 150, 400, 0.1, rng));
    plain.solve(20);
    EXPECT_GT((plain.pose().t - truth.t).norm(), 2.0 * (problem.pose().t - truth.t).norm());
  }
}

TEST(PoseSolver, UnfoundSlotsAndNoMatches)
{
  std::mt19937 rng(2);
  const Pose truth;
  MatchSlots slots = exactMatches(truth, 10, 20, 0.0, rng);
  slots.line_found[3] = 0;
  slots.plane_found[0] = 0;
  slots.plane_found[19] = 0;
  PoseProblem problem(truth, 0.1);
  const auto [lines, planes] = problem.addMatches(slots);
  EXPECT_EQ(lines, 9);
  EXPECT_EQ(planes, 18);
  EXPECT_EQ(problem.matchCount(), 27);

  const Pose start = perturbed(truth, 0.1, 1.0);
  PoseProblem empty(start, 0.1);
  empty.solve(4);  // nothing to solve: the pose stays
  EXPECT_LT((empty.pose().t - start.t).norm(), 1e-12);
  EXPECT_EQ(empty.constraintStrength(10.0), 0.0);
}

// The constraint strength as it was computed before the matches were batched: Ceres's Jacobian of one
// residual block per match (no loss) in the manifold's tangent, J^T J, scaled rotation, smallest eigenvalue.
double ceresConstraintStrength(const Pose& pose, const MatchSlots& slots, double lever_arm)
{
  double q[4] = { pose.q.x(), pose.q.y(), pose.q.z(), pose.q.w() };
  double t[3] = { pose.t.x(), pose.t.y(), pose.t.z() };
  ceres::Problem problem;
  addQuaternionBlock(problem, q);
  problem.AddParameterBlock(t, 3);
  for (std::size_t i = 0; i < slots.lines.size(); ++i)
  {
    const LineMatch& m = slots.lines[i];
    problem.AddResidualBlock(PointToLineResidual::createAutoDiff(m.point, m.a, m.direction), nullptr, q, t);
  }
  for (std::size_t i = 0; i < slots.planes.size(); ++i)
  {
    const PlaneMatch& m = slots.planes[i];
    problem.AddResidualBlock(PointToPlaneResidual::createAutoDiff(m.point, m.normal, m.d), nullptr, q, t);
  }
  ceres::Problem::EvaluateOptions options;
  options.parameter_blocks = { q, t };
  ceres::CRSMatrix crs;
  EXPECT_TRUE(problem.Evaluate(options, nullptr, nullptr, nullptr, &crs));
  EXPECT_EQ(crs.num_cols, 6);
  Eigen::Matrix<double, 6, 6> normal = Eigen::Matrix<double, 6, 6>::Zero();
  for (int row = 0; row < crs.num_rows; ++row)
  {
    Eigen::Matrix<double, 6, 1> j = Eigen::Matrix<double, 6, 1>::Zero();
    for (int k = crs.rows[row]; k < crs.rows[row + 1]; ++k)
    {
      j[crs.cols[k]] = crs.values[k];
    }
    normal += j * j.transpose();
  }
  Eigen::Matrix<double, 6, 1> scale;
  scale << Eigen::Vector3d::Constant(1.0 / lever_arm), Eigen::Vector3d::Ones();
  normal = scale.asDiagonal() * normal * scale.asDiagonal();
  return Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>>(normal).eigenvalues()[0];
}

TEST(PoseSolver, ConstraintStrengthIsCeresJacobians)
{
  std::mt19937 rng(3);
  const Pose pose(Eigen::Quaterniond(Eigen::AngleAxisd(-1.1, Eigen::Vector3d(0.3, 0.1, 1.0).normalized())),
                  Eigen::Vector3d(-4.0, 2.0, 1.0));
  for (const double outliers : { 0.0, 0.3 })  // residuals do not enter: the loss is off
  {
    const MatchSlots slots = exactMatches(pose, 60, 200, outliers, rng);
    PoseProblem problem(pose, 0.1);
    problem.addMatches(slots);
    const double ours = problem.constraintStrength(10.0);
    const double theirs = ceresConstraintStrength(pose, slots, 10.0);
    EXPECT_GT(theirs, 1.0);
    EXPECT_NEAR(ours, theirs, 1e-9 * theirs);
  }
  // Planes that all face one way leave the pose free along them: nothing constrains it there.
  MatchSlots floor = exactMatches(pose, 0, 200, 0.0, rng);
  for (PlaneMatch& m : floor.planes)
  {
    m.normal = Eigen::Vector3d::UnitZ();
    m.d = -(pose.q * m.point + pose.t).z();
  }
  PoseProblem degenerate(pose, 0.1);
  degenerate.addMatches(floor);
  EXPECT_NEAR(degenerate.constraintStrength(10.0), 0.0, 1e-9);
}

TEST(PoseSolver, ThreadsDoNotChangeTheSolution)
{
  std::mt19937 rng(4);
  const Pose truth(Eigen::Quaterniond(Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitY())),
                   Eigen::Vector3d(1.0, 2.0, 3.0));
  const MatchSlots slots = exactMatches(truth, 800, 3000, 0.05, rng);
  Pose solutions[2];
  for (const int threads : { 1, 2 })
  {
    PoseProblem problem(perturbed(truth, 0.03, 0.2), 0.1, threads);
    problem.addMatches(slots);
    problem.solve(4);
    solutions[threads - 1] = problem.pose();
  }
  EXPECT_EQ(solutions[0].t, solutions[1].t);
  EXPECT_EQ(solutions[0].q.coeffs(), solutions[1].q.coeffs());
}

}  // namespace
}  // namespace aloam
