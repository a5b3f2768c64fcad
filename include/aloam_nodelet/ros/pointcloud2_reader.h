// Converts a sensor_msgs/PointCloud2 into the core's point cloud, validating the message layout.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include <sensor_msgs/PointCloud2.h>

#include "aloam_nodelet/core/executor.h"
#include "aloam_nodelet/core/point_types.h"

namespace aloam
{
namespace ros_io
{
struct ReaderOptions
{
  /// Keep at most this many valid points (the first ones in memory order); 0 disables the cap.
  std::size_t max_points = 2'000'000;
  /// Nominal sweep period in seconds. Per-point times spanning more than twice this are rejected.
  double scan_period = 0.1;
  /// Large clouds are decoded in parallel on these threads (the reading stage's); null: on the caller.
  Executor* executor = nullptr;
};

struct ReadReport
{
  /// False when the cloud is unusable; `error` then says why.
  bool ok = false;
  std::string error;
  /// Issues that were repaired or tolerated, each a short sentence.
  std::vector<std::string> warnings;
  /// Points declared by the message (width * height).
  std::size_t points_in = 0;
  /// Points written to the output cloud.
  std::size_t points_out = 0;
  /// Points dropped for NaN/Inf or all-zero xyz. Points neither output nor dropped were not read
  /// (truncated data or the max_points cap; a warning says so).
  std::size_t dropped_invalid = 0;
  /// A usable `ring` field was found and copied.
  bool has_ring = false;
  /// A usable time field was found; output times are seconds since the earliest kept point.
  bool has_time = false;
  /// Name of the time field used ("time", "t" or "timestamp"); empty when none was used.
  std::string time_field;
  /// Raw time of the earliest kept point in seconds, as the driver encoded it (relative to the
  /// header stamp for "time"/"t", absolute for "timestamp"): raw time = output time + time_origin.
  double time_origin = 0.0;
};

/// Bytes of one element of a sensor_msgs/PointField datatype; 0 for an unknown datatype.
std::size_t pointFieldSize(std::uint8_t datatype);

/// Converts `msg` into `out` (unorganized: height 1, is_dense true; organized clouds are flattened
/// row by row in memory order). Handles any endianness, unaligned fields, row padding, FLOAT32 or
/// FLOAT64 coordinates, numeric intensity, integer ring and the time fields `time` (seconds, may be
/// negative), `t` (nanoseconds) and `timestamp` (absolute seconds). Drops points with non-finite or
/// all-zero xyz. Never throws and never reads outside `msg.data`. `out` is always overwritten; it
/// holds the header (frame_id, stamp in microseconds, seq) and the points read, even on error.
ReadReport readPointCloud2(const sensor_msgs::PointCloud2& msg, const ReaderOptions& options, aloam::Cloud& out);

}  // namespace ros_io
}  // namespace aloam
