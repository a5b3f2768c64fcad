// A drive of any length through an endless street, for long-run and benchmark tests: the trajectory is
// analytic and the scene is generated lazily, tile by tile, from a seed, so that memory does not grow with
// the length of the drive and the sensor always meets new territory. ROS-free.
#pragma once

#include <map>
#include <memory>
#include <vector>

#include <Eigen/Geometry>

#include "aloam_nodelet/core/point_types.h"
#include "aloam_nodelet/core/sensor_model.h"
#include "aloam_nodelet/sim/raycaster.h"
#include "aloam_nodelet/sim/scene.h"
#include "aloam_nodelet/sim/trajectories.h"

namespace aloam
{
namespace sim
{
struct LongDriveOptions
{
  unsigned seed = 1;               // same seed, same street and same sweeps
  double speed = 10.0;             // m/s along +x
  double scan_period = 0.1;        // seconds per sweep
  double height_m = 1.8;           // sensor above the ground
  double weave_amplitude_m = 1.0;  // lateral weave within the lane
  double weave_period_s = 16.0;
  double tile_length_m = 250.0;  // the street is generated in tiles of this length
  /// Tiles within this distance (m) of the sensor are in the scene; more than the lidar's range.
  double reach_m = 130.0;
  double range_noise_sigma = 0.01;  // metres
  /// Keep every n-th firing of the sensor (azimuth steps n times the sensor's): fewer points per sweep for
  /// long runs on slow machines; 1 keeps them all.
  int column_step = 1;
};

/// Sweep k covers [k, k + 1) * scan_period of the drive and is stamped at its end. Sweeps are asked for in
/// order (any order works, but going back rebuilds tiles).
class LongDrive
{
public:
  explicit LongDrive(const LongDriveOptions& options = {});

  const LongDriveOptions& options() const { return options_; }
  /// World <- sensor at time t (s since the start of the drive).
  Eigen::Isometry3d poseAt(double t) const { return pose_at_(t); }
  /// Ground truth of sweep k: the sensor pose at its end.
  Eigen::Isometry3d sweepEndPose(long k) const { return poseAt(static_cast<double>(k + 1) * options_.scan_period); }
  double sweepStamp(long k) const { return static_cast<double>(k + 1) * options_.scan_period; }

  /// The scene around sweep k: the tiles within reach of the sensor during it.
  const Scene& sceneForSweep(long k);
  /// Sweep k as the sensor delivers it: points in the sensor frame at their own firing times (motion
  /// distortion), with ring and time; noise seeded by the drive's seed and k.
  Cloud sweep(long k, const SensorModel& sensor);

  /// Tiles generated so far (each tile is generated again if the sensor comes back to it).
  std::size_t tilesGenerated() const { return tiles_generated_; }
  /// Primitives in the current scene (bounded: the scene holds a window of tiles).
  std::size_t scenePrimitives() const { return scene_ ? scene_->size() : 0; }

private:
  std::vector<Primitive> tile(long index);

  LongDriveOptions options_;
  PoseFunction pose_at_;
  long first_tile_ = 0, last_tile_ = -1;  // window of the current scene
  std::map<long, std::vector<Primitive>> tiles_;
  std::unique_ptr<Scene> scene_;
  std::size_t tiles_generated_ = 0;
};

}  // namespace sim
}  // namespace aloam
