// Point-to-line and point-to-plane residuals shared by odometry and mapping.
#pragma once

#include <ceres/ceres.h>
#include <Eigen/Geometry>

namespace aloam
{
/// Applies the pose (q, t) to `p`; `q_data` is in Eigen's (x, y, z, w) order.
template <typename T>
Eigen::Matrix<T, 3, 1> applyPose(const T* q_data, const T* t_data, const Eigen::Vector3d& p)
{
  Eigen::Map<const Eigen::Quaternion<T>> q(q_data);
  Eigen::Map<const Eigen::Matrix<T, 3, 1>> t(t_data);
  return q * p.cast<T>() + t;
}

/// d(q * p) / d(qx, qy, qz, qw) for q * p as Eigen computes it, p + 2 w (v x p) + 2 v x (v x p) with
/// v = (qx, qy, qz): exact for any q, so it matches automatic differentiation of applyPose.
Eigen::Matrix<double, 3, 4> rotationJacobian(const double* q, const Eigen::Vector3d& p);

/// The residuals below with analytic Jacobians (the autodiff functors stay as their reference in the
/// tests): several times cheaper to evaluate than automatic differentiation with 7-wide jets.
class AnalyticPointToLine : public ceres::SizedCostFunction<3, 4, 3>
{
public:
  AnalyticPointToLine(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& u);
  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override;

private:
  Eigen::Vector3d p_, a_;
  Eigen::Matrix3d minus_u_cross_;  // r = -[u]x (x - a)
};

class AnalyticPointToPlane : public ceres::SizedCostFunction<1, 4, 3>
{
public:
  AnalyticPointToPlane(const Eigen::Vector3d& p, const Eigen::Vector3d& n, double d);
  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override;

private:
  Eigen::Vector3d p_, n_;
  double d_;
};

/// Distance of the transformed point from the line through `a` with unit direction `u`, as the 3-vector
/// (x - a) x u, whose norm is the distance.
struct PointToLineResidual
{
  PointToLineResidual(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& u)
    : p_(p), a_(a), u_(u)
  {
  }

  template <typename T>
  bool operator()(const T* q, const T* t, T* residual) const
  {
    const Eigen::Matrix<T, 3, 1> x = applyPose(q, t, p_) - a_.cast<T>();
    Eigen::Map<Eigen::Matrix<T, 3, 1>> r(residual);
    r = x.cross(u_.cast<T>());
    return true;
  }

  static ceres::CostFunction* create(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& u)
  {
    return new AnalyticPointToLine(p, a, u);
  }
  static ceres::CostFunction* createAutoDiff(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                             const Eigen::Vector3d& u)
  {
    return new ceres::AutoDiffCostFunction<PointToLineResidual, 3, 4, 3>(new PointToLineResidual(p, a, u));
  }

  Eigen::Vector3d p_, a_, u_;
};

/// Signed distance of the transformed point from the plane n.x + d = 0 (n a unit normal).
struct PointToPlaneResidual
{
  PointToPlaneResidual(const Eigen::Vector3d& p, const Eigen::Vector3d& n, double d) : p_(p), n_(n), d_(d) {}

  template <typename T>
  bool operator()(const T* q, const T* t, T* residual) const
  {
    residual[0] = n_.cast<T>().dot(applyPose(q, t, p_)) + T(d_);
    return true;
  }

  static ceres::CostFunction* create(const Eigen::Vector3d& p, const Eigen::Vector3d& n, double d)
  {
    return new AnalyticPointToPlane(p, n, d);
  }
  static ceres::CostFunction* createAutoDiff(const Eigen::Vector3d& p, const Eigen::Vector3d& n, double d)
  {
    return new ceres::AutoDiffCostFunction<PointToPlaneResidual, 1, 4, 3>(new PointToPlaneResidual(p, n, d));
  }

  Eigen::Vector3d p_, n_;
  double d_;
};

}  // namespace aloam
