// What scan registration hands to odometry: one sweep, split into LOAM feature clouds.
#pragma once

#include <cstddef>
#include <optional>

#include "aloam_nodelet/core/point_types.h"

namespace aloam
{
/// Counters from one run of scan registration.
struct RegistrationStats
{
  std::size_t points_in = 0;        ///< points offered
  std::size_t points_used = 0;      ///< finite, in range and on a ring
  std::size_t invalid = 0;          ///< NaN / Inf coordinates
  std::size_t out_of_range = 0;     ///< closer than minimum_range or farther than maximum_range
  std::size_t unassigned_ring = 0;  ///< elevation fits no beam of the sensor model (never misfiled)
  std::size_t occluded = 0;         ///< rejected as next to an occluding edge
  std::size_t grazing = 0;          ///< rejected as seen by a beam nearly parallel to the surface
  int rings = 0;                    ///< rings in the output
};

/// One sweep after feature extraction. All clouds are in the sensor frame of the sweep, ordered by
/// ring, and carry ring and time (seconds since the sweep start) in every point.
struct FeatureSet
{
  double stamp = 0.0;  ///< sweep stamp in seconds (the input's)
  double scan_period = 0.1;
  bool has_time = false;  ///< per-point time is meaningful (from the field or from azimuth)
  Cloud sharp;            ///< few, strongest edge points of each sector
  Cloud less_sharp;       ///< edge points (superset of sharp): odometry's edges
  Cloud flat;             ///< few, flattest points of each sector
  Cloud less_flat;        ///< planar points, voxel-filtered (superset of flat, before filtering)
  Cloud full;             ///< every used point
  /// The points of less_sharp whose curvature bends across the ring: mapping's edges
  /// (ScanRegistrationConfig::curvature_across_ring). Unset: mapping takes less_sharp.
  std::optional<Cloud> bending;
  RegistrationStats stats;
};

}  // namespace aloam
