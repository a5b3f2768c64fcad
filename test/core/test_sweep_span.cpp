// The sweep-span solve (a start and an end pose per sweep): its costs' Jacobians, it recovers a motion
// within the sweep, and its start prior holds the start as strongly as it is told to.
#include <cmath>
#include <memory>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "aloam_nodelet/core/sweep_span.h"
#include "test_support.h"

namespace aloam
{
namespace
{
constexpr int kPointsPerPlane = 60;
constexpr double kTruthTurnDeg = 6.0;   // the sensor turns this much over the sweep (60 deg/s at 10 Hz)
constexpr double kStartOffDeg = 2.0;    // the initial end, and in one test the prior, are this far off
constexpr double kRecoveredDeg = 1e-3;  // exact data: the solve recovers the truth to rounding
constexpr double kRecoveredMetres = 1e-4;
constexpr double kFreeStartMaxDeg = 0.05;  // without a prior the start follows the matches ...
constexpr double kHeldStartMaxDeg = 0.05;  // ... with a strong one it stays at the prior

double deg(double rad)
{
  return rad * 180.0 / M_PI;
}

Pose yawPose(double yaw_deg, const Eigen::Vector3d& t)
{
  return Pose(Eigen::Quaterniond(Eigen::AngleAxisd(yaw_deg * M_PI / 180.0, Eigen::Vector3d::UnitZ())), t);
}

// Points on the planes of a room (floor, ceiling, walls at different distances, two slanted panels), each
// taken at a random fraction of a sweep along `truth` and matched to its plane: exact plane matches.
std::vector<SpanPlaneMatch> roomMatches(const SweepSpan& truth)
{
  struct Plane
  {
    Eigen::Vector3d n;
    double d;
  };
  const std::vector<Plane> planes = {
    { Eigen::Vector3d::UnitZ(), 1.5 },
    { -Eigen::Vector3d::UnitZ(), 1.5 },
    { Eigen::Vector3d::UnitX(), 4.0 },
    { -Eigen::Vector3d::UnitX(), 7.0 },
    { Eigen::Vector3d::UnitY(), 2.5 },
    { -Eigen::Vector3d::UnitY(), 3.0 },
    { Eigen::Vector3d(1, 1, 0).normalized(), 5.0 },
    { Eigen::Vector3d(1, -1, 1).normalized(), 6.0 },
  };
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> unit(0.0, 1.0), spread(-2.0, 2.0);
  std::vector<SpanPlaneMatch> out;
  for (const Plane& plane : planes)
  {
    // Two directions within the plane.
    const Eigen::Vector3d u = plane.n.unitOrthogonal(), v = plane.n.cross(u);
    for (int i = 0; i < kPointsPerPlane; ++i)
    {
      const Eigen::Vector3d world = -plane.d * plane.n + spread(rng) * u + spread(rng) * v;
      SpanPlaneMatch m;
      m.s = unit(rng);
      m.match = PlaneMatch{ truth.at(m.s).inverse() * world, plane.n, plane.d };
      out.push_back(m);
    }
  }
  return out;
}
}  // namespace

TEST(SweepSpan, RecoversATurnWithinTheSweep)
{
  const SweepSpan truth{ Pose(), yawPose(kTruthTurnDeg, Eigen::Vector3d(0.14, 0.02, 0.0)) };
  const std::vector<SpanPlaneMatch> planes = roomMatches(truth);
  SweepSpanOptions options;
  options.max_iterations = 20;
  options.huber_delta = 0.0;
  SweepSpan span{ truth.start, yawPose(kTruthTurnDeg - kStartOffDeg, Eigen::Vector3d(0.1, 0.0, 0.0)) };
  ASSERT_TRUE(solveSweepSpan(span, {}, planes, truth.start, options));
  EXPECT_LT(deg(span.end.q.angularDistance(truth.end.q)), kRecoveredDeg);
  EXPECT_LT((span.end.t - truth.end.t).norm(), kRecoveredMetres);
  EXPECT_LT(deg(span.start.q.angularDistance(truth.start.q)), kRecoveredDeg);
  EXPECT_LT((span.start.t - truth.start.t).norm(), kRecoveredMetres);
}

// The analytic Jacobians of a span cost against central differences of its residuals, at a span whose
// quaternions are off the unit sphere and on opposite hemispheres (the blend flips one).
template <typename SpanMatch>
void expectJacobiansMatchDifferences(const SpanMatch& match, int rows)
{
  std::unique_ptr<ceres::CostFunction> cost(spanCost(match));
  std::vector<std::vector<double>> blocks = {
    { 0.1, -0.2, 0.3, 0.95 }, { 0.4, -1.2, 0.3 }, { -0.12, 0.25, -0.28, -0.9 }, { 0.9, -0.8, 0.5 }
  };
  std::vector<double*> parameters;
  for (std::vector<double>& block : blocks)
  {
    parameters.push_back(block.data());
  }
  std::vector<std::vector<double>> jacobians;
  std::vector<double*> jacobian_pointers;
  for (const std::vector<double>& block : blocks)
  {
    jacobians.emplace_back(rows * block.size());
  }
  for (std::vector<double>& jacobian : jacobians)
  {
    jacobian_pointers.push_back(jacobian.data());
  }
  std::vector<double> residual(rows);
  ASSERT_TRUE(cost->Evaluate(parameters.data(), residual.data(), jacobian_pointers.data()));
  const auto residuals = [&]()
  {
    Eigen::VectorXd r(rows);
    EXPECT_TRUE(cost->Evaluate(parameters.data(), r.data(), nullptr));
    return r;
  };
  for (std::size_t b = 0; b < blocks.size(); ++b)
  {
    const int width = static_cast<int>(blocks[b].size());
    for (int c = 0; c < width; ++c)
    {
      const Eigen::VectorXd numeric = test_support::centralDifference(residuals, blocks[b][c]);
      for (int r = 0; r < rows; ++r)
      {
        EXPECT_NEAR(jacobians[b][r * width + c], numeric[r], 1e-6) << "block " << b << " column " << c << " row " << r;
      }
    }
  }
}

TEST(SweepSpan, CostJacobiansMatchDifferences)
{
  SpanPlaneMatch plane;
  plane.s = 0.3;
  plane.match = PlaneMatch{ Eigen::Vector3d(4.0, -2.0, 1.0), Eigen::Vector3d(1, 2, 2).normalized(), -3.0 };
  expectJacobiansMatchDifferences(plane, 1);

  SpanLineMatch line;
  line.s = 0.8;
  line.match.point = Eigen::Vector3d(-3.0, 5.0, 0.5);
  line.match.a = Eigen::Vector3d(1.0, 2.0, 0.0);
  line.match.direction = Eigen::Vector3d(0, 1, 3).normalized();
  expectJacobiansMatchDifferences(line, 3);
  line.match.free_axis = line.match.direction.unitOrthogonal();
  expectJacobiansMatchDifferences(line, 3);
}

TEST(SweepSpan, StartPriorHoldsTheStartAsToldTo)
{
  const SweepSpan truth{ Pose(), yawPose(kTruthTurnDeg, Eigen::Vector3d(0.14, 0.0, 0.0)) };
  const std::vector<SpanPlaneMatch> planes = roomMatches(truth);
  const Pose wrong_prior = yawPose(kStartOffDeg, Eigen::Vector3d::Zero());
  SweepSpanOptions options;
  options.max_iterations = 20;
  options.huber_delta = 0.0;

  options.start_weight = 0.0;  // the matches alone decide
  SweepSpan free_start{ wrong_prior, truth.end };
  ASSERT_TRUE(solveSweepSpan(free_start, {}, planes, wrong_prior, options));
  EXPECT_LT(deg(free_start.start.q.angularDistance(truth.start.q)), kFreeStartMaxDeg);

  options.start_weight = 1e9;  // the prior decides the start, the matches the end
  SweepSpan held{ wrong_prior, truth.end };
  ASSERT_TRUE(solveSweepSpan(held, {}, planes, wrong_prior, options));
  EXPECT_LT(deg(held.start.q.angularDistance(wrong_prior.q)), kHeldStartMaxDeg);
  EXPECT_GT(deg(held.end.q.angularDistance(truth.end.q)), kFreeStartMaxDeg);  // a wrong start bends the end
}

TEST(SweepSpan, BlendedRotationRunsFromStartToEnd)
{
  const SweepSpan span{ yawPose(10.0, Eigen::Vector3d(1, 2, 3)), yawPose(22.0, Eigen::Vector3d(3, 2, 1)) };
  EXPECT_LT(deg(span.at(0.0).q.angularDistance(span.start.q)), 1e-9);
  EXPECT_LT(deg(span.at(1.0).q.angularDistance(span.end.q)), 1e-9);
  EXPECT_NEAR(deg(span.at(0.5).q.angularDistance(span.start.q)), 6.0, 1e-9);  // symmetric: nlerp's midpoint is slerp's
  EXPECT_LT((span.at(0.25).t - Eigen::Vector3d(1.5, 2, 2.5)).norm(), 1e-12);
  // The opposite sign of the same end rotation blends the same way.
  SweepSpan flipped = span;
  flipped.end.q.coeffs() = -flipped.end.q.coeffs();
  EXPECT_LT(deg(flipped.at(0.3).q.angularDistance(span.at(0.3).q)), 1e-9);
}

}  // namespace aloam
