// Point-to-line and point-to-plane residuals shared by odometry and mapping.
#pragma once

#include <vector>

#include <ceres/ceres.h>
#include <Eigen/Geometry>

#include "aloam_nodelet/core/executor.h"

namespace aloam
{
/// A point of the current sweep matched to a line of the reference (through `a`, unit `direction`).
struct LineMatch
{
  Eigen::Vector3d point, a, direction;
  /// A unit vector perpendicular to `direction`, or zero: the match then does not measure the point's offset
  /// from the line along this axis, only along the other one perpendicular to the line (mapping sets it for
  /// lines that lie almost in the scan cone of their point: LaserMappingConfig::line_ring_crossing_deg).
  Eigen::Vector3d free_axis = Eigen::Vector3d::Zero();
};

/// A point of the current sweep matched to a plane of the reference: normal . x + d = 0.
struct PlaneMatch
{
  Eigen::Vector3d point, normal;
  double d = 0.0;
};

/// Applies the pose (q, t) to `p`; `q_data` is in Eigen's (x, y, z, w) order.
template <typename T>
Eigen::Matrix<T, 3, 1> applyPose(const T* q_data, const T* t_data, const Eigen::Vector3d& p)
{
  Eigen::Map<const Eigen::Quaternion<T>> q(q_data);
  Eigen::Map<const Eigen::Matrix<T, 3, 1>> t(t_data);
  return q * p.cast<T>() + t;
}

/// A pose (q, t) prepared for transforming many points with derivatives. q * p as Eigen computes it,
/// p + 2 w (v x p) + 2 v x (v x p) with v = (qx, qy, qz), is linear in p for any q (unit or not, as the
/// solver visits it): q * p = a p, and d(q * p) / d(q_c) = d[c] p for c = qx, qy, qz, qw. Exact, so it
/// matches automatic differentiation of applyPose; per point it costs a few matrix-vector products.
struct PoseTerms
{
  PoseTerms(const double* q, const double* t);
  Eigen::Matrix3d a;
  Eigen::Matrix3d d[4];
  Eigen::Vector3d t;
};

/// d(q) / d(delta) at delta = 0 for the unit-quaternion manifold (Eigen's x, y, z, w order), whose
/// update is q <- [cos|delta|, sin|delta| delta / |delta|] * q, as Ceres's EigenQuaternionManifold (and
/// EigenQuaternionParameterization) define it.
Eigen::Matrix<double, 4, 3> quaternionPlusJacobian(const double* q);

/// Every match of one solve as a single Ceres cost function over (q, t): three residuals per line match,
/// (x - a) x direction, then one per plane match, normal . x + d, with analytic Jacobians. Each match is
/// robustified here with the Huber loss of scale `huber_delta` (<= 0: none), so that the squared
/// residuals sum to Ceres's robust cost, sum rho(|r|^2); the Jacobians are those of the scaled residuals.
/// One residual block instead of one per match: Ceres's bookkeeping per block cost more than the
/// residuals themselves. The matches are evaluated in `threads` chunks on `executor` (null: on the calling
/// thread); results depend on neither. The stages no longer solve with it (PoseProblem::solve works on
/// accumulateMatches' normal equations): it is the Ceres form of their problem, the reference the tests
/// hold PoseProblem::solve and accumulateMatches to.
class MatchResiduals : public ceres::CostFunction
{
public:
  /// Keeps references: the matches must outlive the cost function.
  MatchResiduals(const std::vector<LineMatch>& lines, const std::vector<PlaneMatch>& planes, double huber_delta,
                 int threads, Executor* executor = nullptr);
  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override;

private:
  const std::vector<LineMatch>& lines_;
  const std::vector<PlaneMatch>& planes_;
  double huber_delta_;
  int threads_;
  Executor* executor_;
};

/// Gauss-Newton terms of a set of matches in the manifold's tangent (the rotation delta of
/// quaternionPlusJacobian, then the translation): cost 1/2 sum |r|^2, gradient J^T r, normal matrix J^T J.
struct NormalTerms
{
  Eigen::Matrix<double, 6, 6> normal = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix<double, 6, 1> gradient = Eigen::Matrix<double, 6, 1>::Zero();
  double cost = 0.0;

  void add(const NormalTerms& other);
};

/// Adds the matches with index in [begin, end) to `terms`, counted as MatchResiduals counts them (lines
/// first, then planes), at `pose` (a unit quaternion), each robustified with the Huber loss of scale
/// `huber_delta` (<= 0: none). The same terms as MatchResiduals' rows times quaternionPlusJacobian, up to
/// rounding, at about half the arithmetic: the tangent Jacobian is taken directly.
void accumulateMatches(const std::vector<LineMatch>& lines, const std::vector<PlaneMatch>& planes, int begin, int end,
                       const PoseTerms& pose, double huber_delta, NormalTerms& terms);

/// The projection a line match's residual (x - a) x u goes through: the identity without a free axis, else
/// the identity less the residual direction that only the offset along the free axis moves.
Eigen::Matrix3d freeAxisProjection(const LineMatch& m);

/// The residual of one match at `pose` without any loss (3 values for a line, 1 for a plane) into `r`, and
/// its row-major Jacobians into `jq` (rows x 4) and `jt` (rows x 3), which may be null.
void evaluateLine(const LineMatch& m, const PoseTerms& pose, double* r, double* jq, double* jt);
void evaluatePlane(const PlaneMatch& m, const PoseTerms& pose, double* r, double* jq, double* jt);

/// Distance of the transformed point from the line through `a` with unit direction `u`, as the 3-vector
/// (x - a) x u, whose norm is the distance. Automatic differentiation: the reference of the tests.
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

  static ceres::CostFunction* createAutoDiff(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                             const Eigen::Vector3d& u)
  {
    return new ceres::AutoDiffCostFunction<PointToLineResidual, 3, 4, 3>(new PointToLineResidual(p, a, u));
  }

  Eigen::Vector3d p_, a_, u_;
};

/// Signed distance of the transformed point from the plane n.x + d = 0 (n a unit normal). Automatic
/// differentiation: the reference of the tests.
struct PointToPlaneResidual
{
  PointToPlaneResidual(const Eigen::Vector3d& p, const Eigen::Vector3d& n, double d) : p_(p), n_(n), d_(d) {}

  template <typename T>
  bool operator()(const T* q, const T* t, T* residual) const
  {
    residual[0] = n_.cast<T>().dot(applyPose(q, t, p_)) + T(d_);
    return true;
  }

  static ceres::CostFunction* createAutoDiff(const Eigen::Vector3d& p, const Eigen::Vector3d& n, double d)
  {
    return new ceres::AutoDiffCostFunction<PointToPlaneResidual, 1, 4, 3>(new PointToPlaneResidual(p, n, d));
  }

  Eigen::Vector3d p_, n_;
  double d_;
};

}  // namespace aloam
