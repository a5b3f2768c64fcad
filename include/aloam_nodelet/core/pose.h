// A rigid transform as a unit quaternion and a translation (the layout the solvers optimise).
#pragma once

#include <Eigen/Geometry>

#include "aloam_nodelet/core/point_types.h"

namespace aloam
{
struct Pose
{
  Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();

  Pose() = default;
  Pose(const Eigen::Quaterniond& rotation, const Eigen::Vector3d& translation) : q(rotation), t(translation) {}
  explicit Pose(const Eigen::Isometry3d& iso) : q(iso.rotation()), t(iso.translation()) {}

  Eigen::Isometry3d isometry() const
  {
    Eigen::Isometry3d iso = Eigen::Isometry3d::Identity();
    iso.linear() = q.normalized().toRotationMatrix();
    iso.translation() = t;
    return iso;
  }
  Pose operator*(const Pose& o) const { return Pose(q * o.q, t + q * o.t); }
  Pose inverse() const
  {
    const Eigen::Quaterniond qi = q.conjugate();
    return Pose(qi, -(qi * t));
  }
  Eigen::Vector3d operator*(const Eigen::Vector3d& p) const { return q * p + t; }
  bool isFinite() const { return q.coeffs().allFinite() && t.allFinite(); }
  /// Exactly the default pose (no rotation, no translation).
  bool isIdentity() const { return q.coeffs() == Eigen::Quaterniond::Identity().coeffs() && t.isZero(0.0); }

  /// The pose a fraction `s` of the way from identity to this one (slerp / linear), LOAM's
  /// constant-velocity model within a sweep.
  Pose interpolated(double s) const { return Pose(Eigen::Quaterniond::Identity().slerp(s, q), s * t); }

  /// This motion scaled in time by `s` at constant velocity: the rotation angle about the same axis and
  /// the translation times `s` (the model deskewing uses within a sweep). Unlike interpolated(), `s` may
  /// exceed 1; `s == 1` returns this pose unchanged, bit for bit.
  Pose scaled(double s) const
  {
    if (s == 1.0)
    {
      return *this;
    }
    const Eigen::AngleAxisd rotation(q.normalized());
    return Pose(Eigen::Quaterniond(Eigen::AngleAxisd(s * rotation.angle(), rotation.axis())), s * t);
  }
};

/// Applies `pose` to the coordinates of `p`, keeping its other fields.
inline Point transformPoint(const Pose& pose, const Point& p)
{
  const Eigen::Vector3d v = pose * Eigen::Vector3d(p.x, p.y, p.z);
  Point out = p;
  out.x = static_cast<float>(v.x());
  out.y = static_cast<float>(v.y());
  out.z = static_cast<float>(v.z());
  return out;
}

}  // namespace aloam
