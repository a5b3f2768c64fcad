// Smooth, deterministic sensor trajectories (world <- sensor as a function of time) for the lidar
// simulator. ROS-free.
#pragma once

#include "aloam_nodelet/sim/raycaster.h"
#include "aloam_nodelet/sim/scenes_extra.h"

namespace aloam
{
namespace sim
{
/// A car driving along +x at constant speed with gentle lateral weaves, the sensor `height_m` above
/// the ground profile; heading follows the path tangent, pitch follows the ground slope.
struct CarDriveOptions
{
  double speed = 10.0;             // m/s along x
  double start_x = 10.0;           // metres, x at t = 0
  double height_m = 1.8;           // sensor height above the ground
  double weave_amplitude_m = 1.5;  // lateral weave y = A sin(2 pi t / period)
  double weave_period_s = 12.0;
  GroundProfile ground = GroundProfile::flat();
};

/// A person walking along +x holding the sensor: vertical bobbing, a little roll sway, and yaw
/// bursts (the sensor is turned, the walking direction stays +x): every `burst_interval_s` the yaw
/// rate rises to `burst_rate_rad_s` for `burst_duration_s` (raised-cosine edges included), turning
/// in the pattern left, right, right, left (yaw stays within +-rate * duration).
struct HandHeldOptions
{
  double speed = 1.4;     // m/s along x
  double start_x = 3.0;   // metres
  double height_m = 1.5;  // mean sensor height above the ground
  double bob_amplitude_m = 0.03;
  double bob_frequency_hz = 2.0;
  double roll_amplitude_rad = 0.01;
  double burst_rate_rad_s = 1.5707963267948966;  // 90 deg/s
  double burst_duration_s = 0.5;                 // plateau + one edge (the turn is burst_rate * duration)
  double burst_edge_s = 0.1;                     // length of each raised-cosine edge
  double burst_interval_s = 4.0;
  double first_burst_s = 2.0;
  GroundProfile ground = GroundProfile::flat();
};

/// Straight line along +x at constant speed, `height_m` above the ground, pitch follows the ground.
struct StraightOptions
{
  double speed = 5.0;
  double start_x = 0.0;
  double height_m = 1.8;
  GroundProfile ground = GroundProfile::flat();
};

PoseFunction carDrive(const CarDriveOptions& options);
PoseFunction carDrive(double speed = 10.0, const GroundProfile& ground = GroundProfile::flat());
PoseFunction handHeld(const HandHeldOptions& options);
PoseFunction handHeld(double speed = 1.4, const GroundProfile& ground = GroundProfile::flat());
PoseFunction straight(const StraightOptions& options);
PoseFunction straight(double speed, const GroundProfile& ground = GroundProfile::flat());

/// Yaw rate (rad/s) of the hand-held trajectory at time t (analytic; for tests and diagnostics).
double handHeldYawRate(const HandHeldOptions& options, double t);
/// Yaw (rad) of the hand-held trajectory at time t.
double handHeldYaw(const HandHeldOptions& options, double t);

}  // namespace sim
}  // namespace aloam
