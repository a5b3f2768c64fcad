// PoseProblem: the solve recovers a known pose and takes Ceres's steps, the constraint strength is the one
// Ceres's own Jacobian gives, and threads do not change the result.
#include <algorithm>
#include <cmath>
#include <random>
#include <string>
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
  Executor executor(2);
  for (const int threads : { 1, 2 })
  {
    PoseProblem problem(perturbed(truth, 0.03, 0.2), 0.1, threads, &executor);
    problem.addMatches(slots);
    problem.solve(4);
    solutions[threads - 1] = problem.pose();
  }
  EXPECT_EQ(solutions[0].t, solutions[1].t);
  EXPECT_EQ(solutions[0].q.coeffs(), solutions[1].q.coeffs());
}

// ceres::Solve (Levenberg-Marquardt, DENSE_QR, default options) on the same matches as one MatchResiduals
// block: what PoseProblem::solve replaced.
Pose ceresSolve(const Pose& start, const MatchSlots& slots, double huber_delta, int max_iterations)
{
  std::vector<LineMatch> lines;
  std::vector<PlaneMatch> planes;
  for (std::size_t i = 0; i < slots.lines.size(); ++i)
  {
    if (slots.line_found[i])
    {
      lines.push_back(slots.lines[i]);
    }
  }
  for (std::size_t i = 0; i < slots.planes.size(); ++i)
  {
    if (slots.plane_found[i])
    {
      planes.push_back(slots.planes[i]);
    }
  }
  double q[4] = { start.q.x(), start.q.y(), start.q.z(), start.q.w() };
  double t[3] = { start.t.x(), start.t.y(), start.t.z() };
  ceres::Problem problem;
  addQuaternionBlock(problem, q);
  problem.AddParameterBlock(t, 3);
  problem.AddResidualBlock(new MatchResiduals(lines, planes, huber_delta, 1), nullptr, q, t);
  ceres::Solver::Options options;
  options.linear_solver_type = ceres::DENSE_QR;
  options.max_num_iterations = max_iterations;
  options.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  return Pose(Eigen::Quaterniond(q[3], q[0], q[1], q[2]).normalized(), Eigen::Vector3d(t[0], t[1], t[2]));
}

// The solve takes the steps Ceres takes, up to rounding: after 1, 2, 4 and 10 iterations, from near and far
// starts (far ones have steps rejected and the radius shrunk), with outliers under the Huber loss, with
// few and many matches, and on a floor that leaves directions free.
TEST(PoseSolver, TakesTheStepsCeresTakes)
{
  int compared = 0, moved = 0;
  for (unsigned seed = 1; seed <= 6; ++seed)
  {
    std::mt19937 rng(100 + seed);
    std::uniform_real_distribution<double> uniform(-1.0, 1.0);
    const Pose truth(Eigen::Quaterniond(Eigen::AngleAxisd(
                         3.0 * uniform(rng), Eigen::Vector3d(uniform(rng), uniform(rng), 1.0).normalized())),
                     Eigen::Vector3d(10.0 * uniform(rng), 10.0 * uniform(rng), uniform(rng)));
    const int lines = seed % 2 == 0 ? 8 : 200, planes = seed % 2 == 0 ? 30 : 900;
    MatchSlots slots = exactMatches(truth, lines, planes, seed % 3 == 0 ? 0.0 : 0.2, rng);
    if (seed == 6)
    {
      for (PlaneMatch& m : slots.planes)  // a floor: x, y and the yaw are free
      {
        m.normal = Eigen::Vector3d::UnitZ();
        m.d = -(truth.q * m.point + truth.t).z();
      }
      std::fill(slots.line_found.begin(), slots.line_found.end(), 0);
    }
    for (const double huber_delta : { 0.1, 0.0 })
    {
      for (const auto& [angle, shift] : { std::pair<double, double>{ 0.02, 0.1 }, { 0.3, 2.0 }, { 1.2, 8.0 } })
      {
        if (seed == 6 && angle > 1.0)
        {
          continue;  // far from the floor's pose a single step's free part is noise large enough to tilt it
        }
        const Pose start = perturbed(truth, angle, shift);
        for (const int iterations : { 1, 2, 4, 10 })
        {
          PoseProblem problem(start, huber_delta);
          problem.addMatches(slots);
          problem.solve(iterations);
          const Pose theirs = ceresSolve(start, slots, huber_delta, iterations);
          const Pose ours = problem.pose();
          const std::string where = "seed " + std::to_string(seed) + " huber " + std::to_string(huber_delta) +
                                    " start " + std::to_string(angle) + " iterations " + std::to_string(iterations);
          if (seed != 6)
          {
            EXPECT_LT((ours.t - theirs.t).norm(), 1e-7 * (1.0 + theirs.t.norm())) << where;
            EXPECT_LT(angleBetween(ours, theirs), 1e-8) << where;
          }
          else
          {
            // Along the free directions both steps are rounding noise amplified by the tiny damping, and
            // QR and the normal equations round differently (the yaw differs by up to ~1e-5 rad, and a
            // tolerance test may then end one solve a step earlier): only the constrained parts compare.
            EXPECT_LT(std::fabs(ours.t.z() - theirs.t.z()), 1e-3) << where;
            const Eigen::Vector3d up = ours.q.conjugate() * Eigen::Vector3d::UnitZ();
            EXPECT_LT(std::acos(std::min(1.0, up.dot(theirs.q.conjugate() * Eigen::Vector3d::UnitZ()))), 1e-3) << where;
            EXPECT_EQ(ours.t.head<2>(), start.t.head<2>()) << where;  // no gradient along x and y at all
          }
          ++compared;
          moved += (theirs.t - start.t).norm() > 1e-3;
        }
      }
    }
  }
  EXPECT_EQ(compared, (5 * 3 + 2) * 2 * 4);
  EXPECT_GT(moved, compared / 2);  // the solves went somewhere
}

// A corridor along the world x axis (walls 4 m apart, floor and ceiling 3 m apart) seen from `truth`: the
// planes pin down everything but the translation along x. `weak_planes` planes across the corridor add a
// weak x constraint that disagrees with the truth by `weak_bias` metres (as a far door frame matched to
// the wrong side would); their points lie on the x axis of the sensor, so they constrain no rotation.
MatchSlots corridorMatches(const Pose& truth, int planes_per_side, int weak_planes, double weak_bias, std::mt19937& rng)
{
  std::uniform_real_distribution<double> along(-15.0, 15.0), across(-2.0, 2.0), height(-1.2, 1.8);
  MatchSlots slots;
  slots.resize(0, 4 * planes_per_side + weak_planes);
  int k = 0;
  const auto add = [&](const Eigen::Vector3d& world, const Eigen::Vector3d& normal, double bias)
  {
    slots.planes[k] = PlaneMatch{ truth.inverse() * world, normal, -normal.dot(world) + bias };
    slots.plane_found[k] = 1;
    ++k;
  };
  for (int i = 0; i < planes_per_side; ++i)
  {
    const Eigen::Vector3d o = truth.t;
    add(o + Eigen::Vector3d(along(rng), 2.0, height(rng)), Eigen::Vector3d::UnitY(), 0.0);
    add(o + Eigen::Vector3d(along(rng), -2.0, height(rng)), -Eigen::Vector3d::UnitY(), 0.0);
    add(o + Eigen::Vector3d(along(rng), across(rng), -1.2), Eigen::Vector3d::UnitZ(), 0.0);
    add(o + Eigen::Vector3d(along(rng), across(rng), 1.8), -Eigen::Vector3d::UnitZ(), 0.0);
  }
  for (int i = 0; i < weak_planes; ++i)
  {
    add(truth.t + Eigen::Vector3d(along(rng), 0.0, 0.0), Eigen::Vector3d::UnitX(), weak_bias);
  }
  return slots;
}

// matchAndSolve over fixed matches (the same slots at every search).
MatchSolveResult solveFixed(const MatchSlots& slots, bool remap, double min_constraint, Pose& pose)
{
  MatchSolveOptions options;
  options.outer_iterations = 2;
  options.max_iterations = 10;
  options.min_constraint = min_constraint;
  options.remap = remap;
  return matchAndSolve(
      pose, slots.lines.size(), slots.planes.size(), options,
      [&](int i, const Pose&, double, LineMatch& m)
      {
        m = slots.lines[i];
        return slots.line_found[i] != 0;
      },
      [&](int i, const Pose&, double, PlaneMatch& m)
      {
        m = slots.planes[i];
        return slots.plane_found[i] != 0;
      });
}

// Solution remapping in a corridor: the translation along the corridor is degenerate (3 weak planes,
// eigenvalue 3 against a threshold of 10) and stays exactly at the prior, while the other five directions
// are solved as without remapping; without remapping the weak, biased planes drag x off the prior.
TEST(PoseSolver, RemappingKeepsThePriorAlongTheUnconstrainedDirection)
{
  std::mt19937 rng(5);
  const Pose truth(Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d(0.1, 0.2, 1.0).normalized())),
                   Eigen::Vector3d(4.0, -0.5, 0.3));
  const MatchSlots slots = corridorMatches(truth, 300, 3, 0.4, rng);
  const Pose prior = perturbed(truth, 0.02, 0.2);
  constexpr double kMinConstraint = 10.0;

  Pose remapped = prior;
  const MatchSolveResult on = solveFixed(slots, true, kMinConstraint, remapped);
  Pose plain = prior;
  const MatchSolveResult off = solveFixed(slots, false, kMinConstraint, plain);

  // Along x: the prior exactly with remapping, the biased weak planes without.
  EXPECT_NEAR(remapped.t.x(), prior.t.x(), 1e-9);
  EXPECT_GT(std::fabs(plain.t.x() - prior.t.x()), 0.1);
  // The other directions: solved, and alike with and without remapping.
  EXPECT_NEAR(remapped.t.y(), truth.t.y(), 1e-6);
  EXPECT_NEAR(remapped.t.z(), truth.t.z(), 1e-6);
  EXPECT_LT(angleBetween(remapped, truth), 1e-7);
  EXPECT_NEAR(plain.t.y(), truth.t.y(), 1e-6);
  EXPECT_LT(angleBetween(plain, truth), 1e-7);
  EXPECT_GT(std::fabs(prior.t.y() - truth.t.y()), 0.1);  // so that solving y is a change

  // Reported: one degenerate direction, the world x axis expressed in the sensor frame, "remapped".
  EXPECT_TRUE(on.remapped);
  EXPECT_FALSE(off.remapped);
  ASSERT_EQ(on.degenerate.size(), 1u);
  ASSERT_EQ(off.degenerate.size(), 1u);
  EXPECT_LT(on.constraint, kMinConstraint);
  const DegenerateDirection& d = on.degenerate[0];
  const Eigen::Vector3d x_in_sensor = truth.q.conjugate() * Eigen::Vector3d::UnitX();
  EXPECT_NEAR(std::fabs(d.translation.dot(x_in_sensor)), 1.0, 1e-6);
  EXPECT_NEAR(d.rotation.norm(), 0.0, 1e-6);
  EXPECT_NEAR(d.eigenvalue, 3.0, 1e-6);
  // How weak, against the mean of the five others (all six reported with a threshold above them all, at
  // the same solution as `off`).
  Pose plain_again = prior;
  const MatchSolveResult all = solveFixed(slots, false, 1e12, plain_again);
  ASSERT_EQ(all.degenerate.size(), 6u);
  double others = 0.0;
  for (int i = 1; i < 6; ++i)
  {
    others += all.degenerate[i].eigenvalue / 5.0;
  }
  EXPECT_NEAR(off.degenerate[0].share, off.degenerate[0].eigenvalue / others, 1e-9);
  EXPECT_GT(d.share, 0.0);
  EXPECT_LT(d.share, 0.2);
  EXPECT_NEAR(all.degenerate[5].share, 1.0, 1e-12);  // all six weak: against the strongest
  EXPECT_NE(describe(d).find("% of the constraint of the other directions"), std::string::npos) << describe(d);
  EXPECT_EQ(describe(d).rfind("translation along (", 0), 0u) << describe(d);
  EXPECT_EQ(describe(d).find("rotation"), std::string::npos) << describe(d);
}

// Nothing degenerate: remapping changes nothing, bit for bit.
TEST(PoseSolver, RemappingEqualsThePlainSolveWhenNothingIsDegenerate)
{
  std::mt19937 rng(6);
  const Pose truth(Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitZ())),
                   Eigen::Vector3d(3.0, -1.0, 0.2));
  const MatchSlots slots = exactMatches(truth, 100, 300, 0.05, rng);
  Pose remapped = perturbed(truth, 0.03, 0.3), plain = remapped;
  const MatchSolveResult on = solveFixed(slots, true, 10.0, remapped);
  const MatchSolveResult off = solveFixed(slots, false, 10.0, plain);
  EXPECT_GT(on.constraint, 10.0);
  EXPECT_TRUE(on.degenerate.empty());
  EXPECT_FALSE(on.remapped);
  EXPECT_EQ(on.constraint, off.constraint);
  EXPECT_EQ(remapped.t, plain.t);
  EXPECT_EQ(remapped.q.coeffs(), plain.q.coeffs());
  EXPECT_LT((remapped.t - truth.t).norm(), 0.02);
}

// Every direction degenerate (no matches constrain anything strongly): the pose stays at the prior.
TEST(PoseSolver, RemappingWithEveryDirectionDegenerateKeepsThePrior)
{
  std::mt19937 rng(7);
  const Pose truth;
  const MatchSlots slots = exactMatches(truth, 5, 10, 0.0, rng);
  const Pose prior = perturbed(truth, 0.02, 0.2);
  Pose pose = prior;
  const MatchSolveResult r = solveFixed(slots, true, 1e9, pose);
  EXPECT_EQ(r.degenerate.size(), 6u);
  EXPECT_FALSE(r.remapped);
  EXPECT_NEAR((pose.t - prior.t).norm(), 0.0, 1e-12);
  EXPECT_NEAR(angleBetween(pose, prior), 0.0, 1e-12);
}

TEST(PoseSolver, DescribesDirections)
{
  DegenerateDirection along_x;
  along_x.translation = Eigen::Vector3d(0.99, 0.01, 0.0);
  EXPECT_EQ(describe(along_x), "translation along (1.00, 0.01, 0.00) (forward-backward)");
  along_x.share = 0.031;
  EXPECT_EQ(describe(along_x),
            "translation along (1.00, 0.01, 0.00) (forward-backward): 3.1 % of the constraint of the other directions");
  DegenerateDirection yaw;
  yaw.rotation = Eigen::Vector3d(0.0, 0.0, 0.9);
  yaw.translation = Eigen::Vector3d(0.0, 0.4, 0.0);
  yaw.share = 0.25;
  EXPECT_EQ(describe(yaw),
            "rotation about (0.00, 0.00, 1.00) (yaw) with translation along (0.00, 1.00, 0.00) "
            "(left-right): 25 % of the constraint of the other directions");
  DegenerateDirection oblique;
  oblique.translation = Eigen::Vector3d(0.7, 0.7, 0.0);
  EXPECT_EQ(describe(oblique), "translation along (0.71, 0.71, 0.00)");
  EXPECT_EQ(describe(std::vector<DegenerateDirection>{}), "none");
}

}  // namespace
}  // namespace aloam
