// The analytic residuals against automatic differentiation of the same functors: values and Jacobians
// at random poses (unit and slightly non-unit quaternions, as the solver visits them).
#include <random>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "aloam_nodelet/core/lidar_factors.h"

namespace aloam
{
namespace
{
constexpr double kTolerance = 1e-9;

struct Evaluation
{
  Eigen::VectorXd residual;
  Eigen::MatrixXd dq, dt;
};

Evaluation evaluate(const ceres::CostFunction& cost, const double* q, const double* t)
{
  const int n = cost.num_residuals();
  Evaluation e{ Eigen::VectorXd(n), Eigen::MatrixXd(n, 4), Eigen::MatrixXd(n, 3) };
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> jq(n, 4), jt(n, 3);
  const double* parameters[] = { q, t };
  double* jacobians[] = { jq.data(), jt.data() };
  EXPECT_TRUE(cost.Evaluate(parameters, e.residual.data(), jacobians));
  e.dq = jq;
  e.dt = jt;
  // Residuals alone (no Jacobians requested) must agree too.
  Eigen::VectorXd only(n);
  EXPECT_TRUE(cost.Evaluate(parameters, only.data(), nullptr));
  EXPECT_LT((only - e.residual).norm(), kTolerance);
  return e;
}

void expectSame(const ceres::CostFunction& analytic, const ceres::CostFunction& autodiff, const double* q,
                const double* t)
{
  const Evaluation a = evaluate(analytic, q, t);
  const Evaluation b = evaluate(autodiff, q, t);
  EXPECT_LT((a.residual - b.residual).norm(), kTolerance);
  EXPECT_LT((a.dq - b.dq).norm(), kTolerance) << "analytic\n" << a.dq << "\nautodiff\n" << b.dq;
  EXPECT_LT((a.dt - b.dt).norm(), kTolerance);
}

TEST(LidarFactors, AnalyticJacobiansMatchAutomaticDifferentiation)
{
  std::mt19937 rng(3);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_real_distribution<double> scale(0.98, 1.02);
  const auto random3 = [&] { return Eigen::Vector3d(normal(rng), normal(rng), normal(rng)); };
  for (int trial = 0; trial < 200; ++trial)
  {
    Eigen::Quaterniond rotation = Eigen::Quaterniond(normal(rng), normal(rng), normal(rng), normal(rng)).normalized();
    double q[4] = { rotation.x(), rotation.y(), rotation.z(), rotation.w() };
    if (trial % 2 == 1)
    {
      const double s = scale(rng);  // off the unit sphere, as during a solver step
      for (double& c : q)
      {
        c *= s;
      }
    }
    const Eigen::Vector3d translation = 5.0 * random3();
    const double t[3] = { translation.x(), translation.y(), translation.z() };
    const Eigen::Vector3d p = 20.0 * random3(), a = 20.0 * random3();
    const Eigen::Vector3d u = random3().normalized();

    std::unique_ptr<ceres::CostFunction> line(PointToLineResidual::create(p, a, u));
    std::unique_ptr<ceres::CostFunction> line_reference(PointToLineResidual::createAutoDiff(p, a, u));
    expectSame(*line, *line_reference, q, t);

    const double d = normal(rng) * 10.0;
    std::unique_ptr<ceres::CostFunction> plane(PointToPlaneResidual::create(p, u, d));
    std::unique_ptr<ceres::CostFunction> plane_reference(PointToPlaneResidual::createAutoDiff(p, u, d));
    expectSame(*plane, *plane_reference, q, t);
  }
}

}  // namespace
}  // namespace aloam
