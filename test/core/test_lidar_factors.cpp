// The batched match residuals (MatchResiduals) against automatic differentiation of the per-match
// functors, the robust cost against Ceres's HuberLoss, and the quaternion tangent against Ceres's.
#include <cmath>
#include <memory>
#include <random>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "aloam_nodelet/core/ceres_compat.h"
#include "aloam_nodelet/core/lidar_factors.h"
#include "test_support.h"

namespace aloam
{
namespace
{
using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

struct Evaluation
{
  Eigen::VectorXd residual;
  RowMajor dq, dt;
};

Evaluation evaluate(const ceres::CostFunction& cost, const double* q, const double* t)
{
  const int n = cost.num_residuals();
  Evaluation e{ Eigen::VectorXd(n), RowMajor(n, 4), RowMajor(n, 3) };
  const double* parameters[] = { q, t };
  double* jacobians[] = { e.dq.data(), e.dt.data() };
  EXPECT_TRUE(cost.Evaluate(parameters, e.residual.data(), jacobians));
  // Residuals alone (no Jacobians requested) must agree (to rounding: autodiff takes another path).
  Eigen::VectorXd only(n);
  EXPECT_TRUE(cost.Evaluate(parameters, only.data(), nullptr));
  EXPECT_LE((only - e.residual).lpNorm<Eigen::Infinity>(), 1e-12 * (1.0 + e.residual.lpNorm<Eigen::Infinity>()));
  return e;
}

struct Scene
{
  std::vector<LineMatch> lines;
  std::vector<PlaneMatch> planes;
  double q[4];
  double t[3];
};

// Matches with residuals from centimetres to metres, at a random pose (unit or slightly off the unit
// sphere, as the solver visits them).
Scene randomScene(std::mt19937& rng, int lines, int planes, bool off_unit)
{
  std::normal_distribution<double> normal(0.0, 1.0);
  const auto random3 = [&] { return Eigen::Vector3d(normal(rng), normal(rng), normal(rng)); };
  Scene s;
  const Eigen::Quaterniond rotation =
      Eigen::Quaterniond(normal(rng), normal(rng), normal(rng), normal(rng)).normalized();
  const double scale = off_unit ? 1.015 : 1.0;
  s.q[0] = scale * rotation.x();
  s.q[1] = scale * rotation.y();
  s.q[2] = scale * rotation.z();
  s.q[3] = scale * rotation.w();
  const Eigen::Vector3d translation = 5.0 * random3();
  for (int a = 0; a < 3; ++a)
  {
    s.t[a] = translation[a];
  }
  std::uniform_real_distribution<double> spread(0.0, 1.0);
  for (int i = 0; i < lines; ++i)
  {
    const Eigen::Vector3d p = 20.0 * random3();
    const Eigen::Vector3d x = rotation * p + translation;  // the transformed point, for a near line
    const Eigen::Vector3d u = random3().normalized();
    const Eigen::Vector3d a = x + 3.0 * normal(rng) * u + std::pow(10.0, -2.0 + 2.5 * spread(rng)) * random3();
    s.lines.push_back(LineMatch{ p, a, u });
  }
  for (int i = 0; i < planes; ++i)
  {
    const Eigen::Vector3d p = 20.0 * random3();
    const Eigen::Vector3d x = rotation * p + translation;
    const Eigen::Vector3d n = random3().normalized();
    const double d = -n.dot(x) + std::pow(10.0, -2.0 + 2.5 * spread(rng)) * normal(rng);
    s.planes.push_back(PlaneMatch{ p, n, d });
  }
  return s;
}

TEST(LidarFactors, MatchResidualsMatchAutomaticDifferentiation)
{
  std::mt19937 rng(3);
  for (int trial = 0; trial < 20; ++trial)
  {
    const Scene s = randomScene(rng, 7 + trial, 11 + 2 * trial, trial % 2 == 1);
    const MatchResiduals batch(s.lines, s.planes, 0.0, 1);  // no loss: the plain residuals
    ASSERT_EQ(batch.num_residuals(), static_cast<int>(3 * s.lines.size() + s.planes.size()));
    const Evaluation b = evaluate(batch, s.q, s.t);
    int row = 0;
    const auto expect_rows = [&](const ceres::CostFunction& reference)
    {
      const Evaluation r = evaluate(reference, s.q, s.t);
      const int n = reference.num_residuals();
      EXPECT_LT((b.residual.segment(row, n) - r.residual).norm(), 1e-9);
      EXPECT_LT((b.dq.middleRows(row, n) - r.dq).norm(), 1e-9) << "row " << row;
      EXPECT_LT((b.dt.middleRows(row, n) - r.dt).norm(), 1e-9) << "row " << row;
      row += n;
    };
    for (const LineMatch& m : s.lines)
    {
      std::unique_ptr<ceres::CostFunction> reference(PointToLineResidual::createAutoDiff(m.point, m.a, m.direction));
      expect_rows(*reference);
    }
    for (const PlaneMatch& m : s.planes)
    {
      std::unique_ptr<ceres::CostFunction> reference(PointToPlaneResidual::createAutoDiff(m.point, m.normal, m.d));
      expect_rows(*reference);
    }
  }
}

// The robust residuals must give Ceres's cost and gradient for the same matches as separate residual
// blocks under HuberLoss, and their Jacobians must be the derivatives of the scaled residuals.
TEST(LidarFactors, RobustResidualsGiveTheHuberCostAndGradient)
{
  constexpr double kDelta = 0.1;
  std::mt19937 rng(5);
  for (int trial = 0; trial < 10; ++trial)
  {
    Scene s = randomScene(rng, 40, 120, false);
    const MatchResiduals batch(s.lines, s.planes, kDelta, 1);
    const Evaluation b = evaluate(batch, s.q, s.t);

    ceres::Problem::Options options;
    options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    ceres::HuberLoss loss(kDelta);
    ceres::Problem problem(options);
    for (const LineMatch& m : s.lines)
    {
      problem.AddResidualBlock(PointToLineResidual::createAutoDiff(m.point, m.a, m.direction), &loss, s.q, s.t);
    }
    for (const PlaneMatch& m : s.planes)
    {
      problem.AddResidualBlock(PointToPlaneResidual::createAutoDiff(m.point, m.normal, m.d), &loss, s.q, s.t);
    }
    double cost = 0.0;
    std::vector<double> gradient;
    ceres::Problem::EvaluateOptions evaluate_options;
    evaluate_options.parameter_blocks = { s.q, s.t };
    ASSERT_TRUE(problem.Evaluate(evaluate_options, &cost, nullptr, &gradient, nullptr));
    EXPECT_NEAR(0.5 * b.residual.squaredNorm(), cost, 1e-9 * (1.0 + cost));
    Eigen::Matrix<double, 7, 1> ours;
    ours << b.dq.transpose() * b.residual, b.dt.transpose() * b.residual;
    const Eigen::Map<const Eigen::Matrix<double, 7, 1>> theirs(gradient.data());
    EXPECT_LT((ours - theirs).norm(), 1e-8 * (1.0 + theirs.norm())) << ours.transpose() << "\n" << theirs.transpose();

    // Central differences of the scaled residuals, away from the kink of the loss at |r| = delta, which a
    // difference step would straddle.
    const Eigen::VectorXd plain = evaluate(MatchResiduals(s.lines, s.planes, 0.0, 1), s.q, s.t).residual;
    std::vector<char> near_kink(static_cast<std::size_t>(plain.size()), 0);
    for (int row = 0; row < plain.size();)
    {
      const int n = row < static_cast<int>(3 * s.lines.size()) ? 3 : 1;
      const bool near = std::fabs(plain.segment(row, n).norm() - kDelta) < 1e-3 * kDelta;
      for (int i = 0; i < n; ++i, ++row)
      {
        near_kink[static_cast<std::size_t>(row)] = near;
      }
    }
    const auto residuals = [&]() { return evaluate(batch, s.q, s.t).residual; };
    for (int block = 0; block < 2; ++block)
    {
      double* parameter = block == 0 ? s.q : s.t;
      for (int c = 0; c < (block == 0 ? 4 : 3); ++c)
      {
        Eigen::VectorXd numeric = test_support::centralDifference(residuals, parameter[c]);
        Eigen::VectorXd analytic = block == 0 ? Eigen::VectorXd(b.dq.col(c)) : Eigen::VectorXd(b.dt.col(c));
        for (std::size_t row = 0; row < near_kink.size(); ++row)
        {
          if (near_kink[row])
          {
            numeric[static_cast<Eigen::Index>(row)] = analytic[static_cast<Eigen::Index>(row)] = 0.0;
          }
        }
        Eigen::Index worst = 0;
        const double error = (numeric - analytic).cwiseAbs().maxCoeff(&worst);
        EXPECT_LT(error, 1e-6 * (1.0 + analytic.lpNorm<Eigen::Infinity>()))
            << "block " << block << " column " << c << " row " << worst << " numeric " << numeric[worst] << " analytic "
            << analytic[worst] << " residual " << b.residual[worst];
      }
    }
  }
}

TEST(LidarFactors, ThreadsDoNotChangeTheResiduals)
{
  std::mt19937 rng(7);
  const Scene s = randomScene(rng, 900, 2500, true);  // several chunks of work
  const Evaluation one = evaluate(MatchResiduals(s.lines, s.planes, 0.1, 1), s.q, s.t);
  const Evaluation two = evaluate(MatchResiduals(s.lines, s.planes, 0.1, 2), s.q, s.t);
  EXPECT_EQ(one.residual, two.residual);
  EXPECT_EQ(one.dq, two.dq);
  EXPECT_EQ(one.dt, two.dt);
}

TEST(LidarFactors, QuaternionTangentMatchesCeres)
{
  std::mt19937 rng(11);
  std::normal_distribution<double> normal(0.0, 1.0);
  for (int trial = 0; trial < 50; ++trial)
  {
    const Eigen::Quaterniond r = Eigen::Quaterniond(normal(rng), normal(rng), normal(rng), normal(rng)).normalized();
    const double q[4] = { r.x(), r.y(), r.z(), r.w() };
    Eigen::Matrix<double, 4, 3, Eigen::RowMajor> theirs;
#if ALOAM_CERES_HAS_MANIFOLDS
    ASSERT_TRUE(ceres::EigenQuaternionManifold().PlusJacobian(q, theirs.data()));
#else
    ASSERT_TRUE(ceres::EigenQuaternionParameterization().ComputeJacobian(q, theirs.data()));
#endif
    EXPECT_LT((quaternionPlusJacobian(q) - theirs).norm(), 1e-15);
  }
}

// PoseProblem's normal equations (accumulateMatches) are MatchResiduals' rows taken into the manifold's
// tangent: J = [dq * plus, dt], normal J^T J, gradient J^T r, cost |r|^2 / 2, with and without the loss.
TEST(LidarFactors, NormalTermsAreTheResidualsInTheTangent)
{
  std::mt19937 rng(13);
  for (int trial = 0; trial < 10; ++trial)
  {
    Scene s = randomScene(rng, 30 + 10 * trial, 100, false);
    for (const double delta : { 0.0, 0.1, 1.0 })
    {
      const Evaluation e = evaluate(MatchResiduals(s.lines, s.planes, delta, 1), s.q, s.t);
      Eigen::MatrixXd j(e.residual.size(), 6);
      j.leftCols(3) = e.dq * quaternionPlusJacobian(s.q);
      j.rightCols(3) = e.dt;
      const Eigen::MatrixXd normal = j.transpose() * j;
      const Eigen::VectorXd gradient = j.transpose() * e.residual;
      const double cost = 0.5 * e.residual.squaredNorm();

      // In three pieces, as PoseProblem adds blocks: the sums do not depend on where the cuts fall.
      const int n = static_cast<int>(s.lines.size() + s.planes.size());
      NormalTerms terms;
      const PoseTerms pose(s.q, s.t);
      for (const auto& [begin, end] : { std::pair<int, int>{ 0, 7 }, { 7, n - 5 }, { n - 5, n } })
      {
        accumulateMatches(s.lines, s.planes, begin, end, pose, delta, terms);
      }
      EXPECT_LT((terms.normal - normal).norm(), 1e-10 * normal.norm()) << "delta " << delta;
      EXPECT_LT((terms.gradient - gradient).norm(), 1e-10 * (1.0 + gradient.norm())) << "delta " << delta;
      EXPECT_NEAR(terms.cost, cost, 1e-12 * cost) << "delta " << delta;
      EXPECT_EQ(terms.normal, terms.normal.transpose());
    }
  }
}

}  // namespace
}  // namespace aloam
