#include "aloam_nodelet/core/scan_context.h"

#include <algorithm>
#include <cmath>

namespace aloam
{
double yawOf(const Pose& pose)
{
  const Eigen::Matrix3d R = pose.q.normalized().toRotationMatrix();
  return std::atan2(R(1, 0), R(0, 0));
}

Eigen::Quaterniond levelling(const Pose& pose)
{
  return Eigen::Quaterniond(Eigen::AngleAxisd(-yawOf(pose), Eigen::Vector3d::UnitZ())) * pose.q.normalized();
}

ScanContext ScanContext::compute(const Cloud& corners, const Cloud& surfs, const Pose& pose,
                                 const ScanContextConfig& config)
{
  const int rings = std::max(config.rings, 1), sectors = std::max(config.sectors, 1);
  Eigen::MatrixXf cells = Eigen::MatrixXf::Zero(rings, sectors);
  const Eigen::Matrix3d level = levelling(pose).toRotationMatrix();
  for (const Cloud* cloud : { &corners, &surfs })
  {
    for (const Point& p : cloud->points)
    {
      const Eigen::Vector3d v = level * Eigen::Vector3d(p.x, p.y, p.z);
      const double range = std::hypot(v.x(), v.y());
      if (!v.allFinite() || range >= config.max_range || range < 1e-3)
      {
        continue;
      }
      const int ring = std::min(rings - 1, static_cast<int>(range / config.max_range * rings));
      const double azimuth = std::atan2(v.y(), v.x()) + M_PI;  // [0, 2 pi]
      const int sector = std::min(sectors - 1, static_cast<int>(azimuth / (2.0 * M_PI) * sectors));
      float& cell = cells(ring, sector);
      cell = std::max(cell, static_cast<float>(std::max(0.0, v.z() + config.lift)));
    }
  }
  return fromCells(cells);
}

ScanContext ScanContext::fromCells(const Eigen::MatrixXf& cells)
{
  ScanContext sc;
  if (cells.size() == 0)
  {
    return sc;
  }
  sc.sectors_ = static_cast<int>(cells.cols());
  sc.cells_ = cells;
  sc.ring_key_ = cells.rowwise().mean();
  sc.column_norms_ = cells.colwise().norm().transpose();
  return sc;
}

ScanContextMatch ScanContext::match(const ScanContext& reference) const
{
  ScanContextMatch best;
  if (empty() || reference.empty() || cells_.rows() != reference.cells_.rows() || sectors_ != reference.sectors_)
  {
    return best;
  }
  const int n = sectors_;
  for (int shift = 0; shift < n; ++shift)
  {
    // Query column (c + shift) against reference column c, over the columns occupied in both.
    double sum = 0.0;
    int used = 0;
    for (int c = 0; c < n; ++c)
    {
      const int q = (c + shift) % n;
      const float na = column_norms_[q], nb = reference.column_norms_[c];
      if (na <= 0.0f || nb <= 0.0f)
      {
        continue;
      }
      sum += 1.0 - cells_.col(q).dot(reference.cells_.col(c)) / (na * nb);
      ++used;
    }
    if (used < std::max(1, n / 4))  // too few sectors seen from both places to compare them
    {
      continue;
    }
    const double distance = sum / used;
    if (distance < best.distance)
    {
      best.distance = distance;
      best.shift = shift;
    }
  }
  // A place at azimuth a in the reference frame lies at a - yaw in the query's: query column c + shift
  // matching reference column c means yaw = -shift sectors.
  int s = best.shift > n / 2 ? best.shift - n : best.shift;
  best.yaw = -2.0 * M_PI * s / n;
  return best;
}

}  // namespace aloam
