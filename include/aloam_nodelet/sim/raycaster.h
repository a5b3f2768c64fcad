// Spinning-lidar simulator: casts one sweep of a SensorModel into a Scene, with real motion
// distortion (every column is fired from the sensor pose at its own time).
#pragma once

#include <functional>
#include <vector>

#include <Eigen/Geometry>

#include "aloam_nodelet/core/point_types.h"
#include "aloam_nodelet/core/sensor_model.h"
#include "aloam_nodelet/sim/scene.h"

namespace aloam
{
namespace sim
{
/// Options of one simulated sweep.
struct ScanOptions
{
  double range_noise_sigma = 0.0;    // metres, Gaussian noise added along the ray
  double dropout_probability = 0.0;  // chance that a return is dropped
  double min_range = 0.5;            // metres; closer returns are omitted
  double max_range = 120.0;          // metres; farther returns are omitted
  double start_azimuth_rad = 0.0;    // azimuth (sensor frame) of the first column
  unsigned seed = 0;                 // seed of noise and dropout (vary it between sweeps)
};

/// Sensor pose at time t (seconds since the start of the sweep): world <- sensor.
using PoseFunction = std::function<Eigen::Isometry3d(double t)>;

/// Scale of the simulated intensity: reflectivity 1 hit head-on gives this value.
constexpr double kMaxIntensity = 255.0;

/// Simulates one sweep. The sensor spins clockwise seen from above: column c (of
/// model.columns()) fires at t = c / columns * scanPeriod with sensor-frame azimuth
/// start_azimuth_rad - 2 pi c / columns, all beams at once. Each ray is cast from
/// sensor_pose_at(t) and its point is reported in the sensor frame at that time. Output order is
/// column-major (for each column rings 0..n-1); misses, dropped and out-of-range returns are
/// omitted. Points carry ring, time and an intensity in [0, 255] (surface reflectivity times the
/// cosine of the incidence angle). Noise and dropout depend only on (seed, column, ring).
/// If `surface_ids` is given it receives the scene surface id of every point (parallel to the cloud).
Cloud scan(const Scene& scene, const SensorModel& model, const PoseFunction& sensor_pose_at, const ScanOptions& options,
           std::vector<int>* surface_ids = nullptr);

/// One sweep from a fixed pose (world <- sensor).
Cloud scanStatic(const Scene& scene, const SensorModel& model, const Eigen::Isometry3d& pose,
                 const ScanOptions& options, std::vector<int>* surface_ids = nullptr);

}  // namespace sim
}  // namespace aloam
