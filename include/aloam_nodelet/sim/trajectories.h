// Smooth, deterministic sensor trajectories (world <- sensor as a function of time) for the lidar
// simulator. ROS-free.
#pragma once

#include <vector>

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
/// Optionally the walker stops every `stop_interval_s` (from `first_stop_s`): the speed falls to zero
/// over `stop_edge_s` (raised cosine), stays zero for `stop_still_s`, and rises again over `stop_edge_s`.
/// Bobbing and sway follow the walked distance, so the sensor is completely still while standing
/// (unless a yaw burst falls into the stop).
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
  double stop_interval_s = 0.0;  // 0: no stops; otherwise at least stop_still_s + 2 * stop_edge_s
  double first_stop_s = 3.5;     // start of the first deceleration
  double stop_edge_s = 0.4;
  double stop_still_s = 1.0;
  double pitch_amplitude_rad = 0.0;  // pitch sway, a quarter period after the roll sway
  /// When not empty: the start times (s) of the yaw bursts, ascending (same left, right, right, left
  /// pattern), instead of one every burst_interval_s from first_burst_s.
  std::vector<double> burst_times_s;
  /// > 0: the walker stands still for this long at the start, then speeds up over stop_edge_s.
  double start_rest_s = 0.0;
  GroundProfile ground = GroundProfile::flat();
};

/// Hand-held walk with 120 deg/s yaw bursts (60 deg turns every 3 s) and a full stop (1 s standing
/// still) every 6 s, timed so that the stands fall between bursts.
HandHeldOptions handHeldBurstsOptions();

/// Distance walked along x (metres from start_x) by time t, and the walking speed at t.
double handHeldDistance(const HandHeldOptions& options, double t);
double handHeldSpeed(const HandHeldOptions& options, double t);

/// A hand-held walk that follows a path with one turn: straight from `start_xy` along `start_heading`,
/// then after `turn_start_m` metres a turn of `turn_angle_rad` over `turn_length_m` metres of path
/// (the heading follows a smoothstep in distance, so the yaw rate rises and falls smoothly), then
/// straight on. The sensor looks along the path with a small yaw sway, bobs and rolls like handHeld.
struct TurnWalkOptions
{
  double speed = 1.4;
  Eigen::Vector2d start_xy = Eigen::Vector2d(2.0, 0.0);
  double start_heading = 0.0;
  double turn_start_m = 10.0;
  double turn_angle_rad = 1.5707963267948966;  // 90 deg, to the left
  double turn_length_m = 2.5;
  double height_m = 1.5;
  double bob_amplitude_m = 0.03;
  double bob_frequency_hz = 2.0;
  double roll_amplitude_rad = 0.01;
  double yaw_sway_rad = 0.03;  // at half the bobbing frequency
};

/// How a hand-held sensor sways as it is carried: it bobs at bob_frequency_hz, and rolls and sways in yaw at
/// half that frequency.
struct WalkSway
{
  double height_m = 1.5;  // mean height above the walking surface
  double bob_amplitude_m = 0.03;
  double bob_frequency_hz = 2.0;
  double roll_amplitude_rad = 0.01;
  double yaw_sway_rad = 0.03;
};
/// world <- sensor of a sensor carried at `xy` looking along `heading` (rad), swaying as `sway` says at time t.
Eigen::Isometry3d swayedPose(const Eigen::Vector2d& xy, double heading, double t, const WalkSway& sway);

/// Displacement (in the frame of the heading before the turn: x forward, y left) over the turn itself.
Eigen::Vector2d turnDisplacement(double turn_angle_rad, double turn_length_m);
/// Heading of the path (rad) after `distance_m` metres.
double turnWalkHeading(const TurnWalkOptions& options, double distance_m);
/// A turn walk through the L of officeScene(options): starts 2 m after the first corridor's end wall
/// on its centerline and turns so that it ends up on the second corridor's centerline.
TurnWalkOptions officeTurnWalk(const OfficeOptions& office = OfficeOptions());
PoseFunction handHeldTurn(const TurnWalkOptions& options);

/// A slow hand-held climb of stairsScene(options): starts 3 m before the first riser, 0.6 m/s
/// horizontally, 1.5 m above stairsProfile, gentle 45 deg/s look-arounds.
HandHeldOptions stairsWalkOptions(const StairsOptions& stairs = StairsOptions());

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

/// Start times (s) of the sweeps published over `duration_s` by a sensor sweeping every `period_s` when
/// only every `keep_every`-th sweep is kept (a throttled topic): sweeps 0, N, 2N, ... of those that end
/// by duration_s. Throws std::invalid_argument for a non-positive period or keep_every < 1.
std::vector<double> publishedSweepStarts(double duration_s, double period_s, int keep_every = 1);

}  // namespace sim
}  // namespace aloam
