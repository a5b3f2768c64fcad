// Point types shared by every stage of the LOAM core.
#pragma once

#include <cmath>
#include <cstdint>

#define PCL_NO_PRECOMPILE
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

namespace aloam
{
/// A lidar return with its beam (ring) and its time within the sweep.
/// `time` is seconds since the start of the sweep; `ring` counts beams from the lowest elevation up.
struct EIGEN_ALIGN16 PointXYZIRT
{
  PCL_ADD_POINT4D;
  float intensity;
  float time;
  std::uint16_t ring;
  PCL_MAKE_ALIGNED_OPERATOR_NEW
};

using Point = PointXYZIRT;
using Cloud = pcl::PointCloud<Point>;

/// True when all three coordinates are finite.
inline bool isFinite(const Point& p)
{
  return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z);
}

/// Marks `cloud` as an unorganized list of finite points (height 1, width = size), as every cloud the
/// core produces is.
inline void setUnorganized(Cloud& cloud)
{
  cloud.width = static_cast<std::uint32_t>(cloud.points.size());
  cloud.height = 1;
  cloud.is_dense = true;
}

}  // namespace aloam

POINT_CLOUD_REGISTER_POINT_STRUCT(aloam::PointXYZIRT,
                                  (float, x, x)(float, y, y)(float, z, z)(float, intensity,
                                                                          intensity)(float, time, time)(std::uint16_t,
                                                                                                        ring, ring))
