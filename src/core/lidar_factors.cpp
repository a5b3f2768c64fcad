#include "aloam_nodelet/core/lidar_factors.h"

namespace aloam
{
namespace
{
Eigen::Matrix3d cross(const Eigen::Vector3d& v)
{
  Eigen::Matrix3d m;
  m << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return m;
}
}  // namespace

Eigen::Matrix<double, 3, 4> rotationJacobian(const double* q, const Eigen::Vector3d& p)
{
  const Eigen::Vector3d v(q[0], q[1], q[2]);
  const double w = q[3];
  Eigen::Matrix<double, 3, 4> j;
  // d/dv: 2 w (v x p) -> -2 w [p]x;  2 v x (v x p) = 2 (v (v.p) - p (v.v)) -> 2 ((v.p) I + v p^T - 2 p v^T).
  j.leftCols<3>() = -2.0 * w * cross(p) +
                    2.0 * (v.dot(p) * Eigen::Matrix3d::Identity() + v * p.transpose() - 2.0 * p * v.transpose());
  j.col(3) = 2.0 * v.cross(p);
  return j;
}

AnalyticPointToLine::AnalyticPointToLine(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& u)
  : p_(p), a_(a), minus_u_cross_(-cross(u))
{
}

bool AnalyticPointToLine::Evaluate(double const* const* parameters, double* residuals, double** jacobians) const
{
  const Eigen::Matrix<double, 3, 1> x = applyPose(parameters[0], parameters[1], p_);
  Eigen::Map<Eigen::Vector3d> r(residuals);
  r = minus_u_cross_ * (x - a_);
  if (jacobians != nullptr)
  {
    // Ceres wants row-major Jacobians.
    if (jacobians[0] != nullptr)
    {
      Eigen::Map<Eigen::Matrix<double, 3, 4, Eigen::RowMajor>> dq(jacobians[0]);
      dq = minus_u_cross_ * rotationJacobian(parameters[0], p_);
    }
    if (jacobians[1] != nullptr)
    {
      Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> dt(jacobians[1]);
      dt = minus_u_cross_;
    }
  }
  return true;
}

AnalyticPointToPlane::AnalyticPointToPlane(const Eigen::Vector3d& p, const Eigen::Vector3d& n, double d)
  : p_(p), n_(n), d_(d)
{
}

bool AnalyticPointToPlane::Evaluate(double const* const* parameters, double* residuals, double** jacobians) const
{
  residuals[0] = n_.dot(applyPose(parameters[0], parameters[1], p_)) + d_;
  if (jacobians != nullptr)
  {
    if (jacobians[0] != nullptr)
    {
      Eigen::Map<Eigen::Matrix<double, 1, 4>> dq(jacobians[0]);
      dq = n_.transpose() * rotationJacobian(parameters[0], p_);
    }
    if (jacobians[1] != nullptr)
    {
      Eigen::Map<Eigen::Matrix<double, 1, 3>> dt(jacobians[1]);
      dt = n_.transpose();
    }
  }
  return true;
}

}  // namespace aloam
