#include "aloam_nodelet/sim/trajectories.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <stdexcept>
#include <vector>

namespace aloam
{
namespace sim
{
namespace
{
constexpr double kPi = 3.14159265358979323846;
constexpr int kBurstPatternLength = 4;
constexpr int kTurnNodes = 1000;  // table of positions along a turn
constexpr int kTurnSubsteps = 8;  // Simpson sub-intervals per table interval (even)
constexpr double kDegToRad = kPi / 180.0;
// handHeldBurstsOptions.
constexpr double kBurstsRateDegS = 120.0;
constexpr double kBurstsInterval = 3.0;
constexpr double kBurstsStopInterval = 6.0;
constexpr double kBurstsFirstStop = 3.5;
// officeTurnWalk / stairsWalkOptions.
constexpr double kOfficeStartX = 2.0;
constexpr double kStairsSpeed = 0.6;
constexpr double kStairsStartX = -3.0;
constexpr double kStairsBob = 0.04;
constexpr double kStairsBurstRateDegS = 45.0;

/// Integral from -infinity to x of a smooth slope ramp rising from 0 to 1 (smoothstep
/// 3 u^2 - 2 u^3) over [center - half_blend, center + half_blend].
double rampIntegral(double x, double center, double half_blend)
{
  if (half_blend <= 0.0)
  {
    return std::max(0.0, x - center);
  }
  if (x <= center - half_blend)
  {
    return 0.0;
  }
  if (x >= center + half_blend)
  {
    return x - center;
  }
  const double width = 2.0 * half_blend;
  const double u = (x - (center - half_blend)) / width;
  return width * (u * u * u - 0.5 * u * u * u * u);
}

/// The smooth slope ramp itself (0 before, 1 after, smoothstep in between; C1).
double ramp(double x, double center, double half_blend)
{
  if (half_blend <= 0.0)
  {
    return x >= center ? 1.0 : 0.0;
  }
  const double u = std::clamp((x - (center - half_blend)) / (2.0 * half_blend), 0.0, 1.0);
  return u * u * (3.0 - 2.0 * u);
}

/// Rotation of a vehicle with the given heading (about z) and pitch (nose up positive).
Eigen::Matrix3d headingPitch(double heading, double pitch_up)
{
  return (Eigen::AngleAxisd(heading, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(-pitch_up, Eigen::Vector3d::UnitY()))
      .toRotationMatrix();
}

/// Turn direction of burst i: left, right, right, left, ...
double burstSign(long index)
{
  const long phase = ((index % kBurstPatternLength) + kBurstPatternLength) % kBurstPatternLength;
  return (phase == 0 || phase == 3) ? 1.0 : -1.0;
}

/// Yaw after `index` complete bursts, in units of one turn (pattern +1, 0, -1, 0).
double completedTurns(long index)
{
  const long phase = ((index % kBurstPatternLength) + kBurstPatternLength) % kBurstPatternLength;
  static constexpr double kTurns[kBurstPatternLength] = { 0.0, 1.0, 0.0, -1.0 };
  return kTurns[phase];
}

/// Unit-rate burst profile: rate at tau seconds into a burst (raised-cosine edges of length `edge`,
/// plateau until `duration`, falling edge until duration + edge).
double burstRate(double tau, double duration, double edge)
{
  if (tau < 0.0 || tau >= duration + edge)
  {
    return 0.0;
  }
  if (tau < edge)
  {
    return 0.5 * (1.0 - std::cos(kPi * tau / edge));
  }
  if (tau < duration)
  {
    return 1.0;
  }
  return 0.5 * (1.0 + std::cos(kPi * (tau - duration) / edge));
}

/// Integral of burstRate from 0 to tau (equals `duration` once the burst is over).
double burstAngle(double tau, double duration, double edge)
{
  if (tau <= 0.0)
  {
    return 0.0;
  }
  if (tau < edge)
  {
    return 0.5 * (tau - edge / kPi * std::sin(kPi * tau / edge));
  }
  if (tau < duration)
  {
    return 0.5 * edge + (tau - edge);
  }
  if (tau < duration + edge)
  {
    const double s = tau - duration;
    return duration - 0.5 * edge + 0.5 * (s + edge / kPi * std::sin(kPi * s / edge));
  }
  return duration;
}
double smoothstep(double u)
{
  u = std::clamp(u, 0.0, 1.0);
  return u * u * (3.0 - 2.0 * u);
}

/// Time lost to standing at the start by time t (the speed rises over stop_edge_s after start_rest_s).
double startLostTime(const HandHeldOptions& o, double t)
{
  if (o.start_rest_s <= 0.0 || t <= 0.0)
  {
    return 0.0;
  }
  if (t <= o.start_rest_s)
  {
    return t;
  }
  // The speed rises like the falling edge of a stop: lost time = rest + edge - the rise's integral.
  const double s = std::min(t - o.start_rest_s, o.stop_edge_s);
  return o.start_rest_s + s - burstAngle(s, o.stop_edge_s, o.stop_edge_s);
}

/// Time spent walking by time t (t minus the time lost to the stops, weighted by the speed dip).
double walkedTime(const HandHeldOptions& o, double t)
{
  const double since_first = t - o.first_stop_s;
  const double start_lost = startLostTime(o, t);
  if (o.stop_interval_s <= 0.0 || since_first <= 0.0)
  {
    return t - start_lost;
  }
  const double dip = o.stop_edge_s + o.stop_still_s;  // burst-profile "duration" of one stop
  const long index = static_cast<long>(std::floor(since_first / o.stop_interval_s));
  const double tau = since_first - static_cast<double>(index) * o.stop_interval_s;
  return t - start_lost - static_cast<double>(index) * dip - burstAngle(tau, dip, o.stop_edge_s);
}

/// Heading of a turn of `angle` spread over `length` metres, `s` metres into it.
double turnHeading(double angle, double length, double s)
{
  return angle * smoothstep(s / length);
}

/// Simpson integral of the unit heading vector over [s0, s1] of a turn.
Eigen::Vector2d integrateTurn(double angle, double length, double s0, double s1, int substeps)
{
  const double h = (s1 - s0) / substeps;
  Eigen::Vector2d sum = Eigen::Vector2d::Zero();
  for (int i = 0; i <= substeps; ++i)
  {
    const double weight = (i == 0 || i == substeps) ? 1.0 : (i % 2 == 1 ? 4.0 : 2.0);
    const double heading = turnHeading(angle, length, s0 + i * h);
    sum += weight * Eigen::Vector2d(std::cos(heading), std::sin(heading));
  }
  return sum * h / 3.0;
}

Eigen::Vector2d direction(double heading)
{
  return Eigen::Vector2d(std::cos(heading), std::sin(heading));
}

/// The bursts at options.burst_times_s, signed left, right, right, left, ... and shaped by `profile`
/// (burstRate for the yaw rate, burstAngle for the yaw), times the burst rate.
double sumOfTimedBursts(const HandHeldOptions& options, double t, double (*profile)(double, double, double))
{
  double sum = 0.0;
  for (std::size_t i = 0; i < options.burst_times_s.size(); ++i)
  {
    sum += burstSign(static_cast<long>(i)) *
           profile(t - options.burst_times_s[i], options.burst_duration_s, options.burst_edge_s);
  }
  return options.burst_rate_rad_s * sum;
}

}  // namespace

GroundProfile GroundProfile::flat()
{
  GroundProfile profile;
  profile.grade = 0.0;
  return profile;
}

double GroundProfile::heightAt(double x) const
{
  const double half_blend = 0.5 * blend_length_m;
  return grade * (rampIntegral(x, start_x, half_blend) - rampIntegral(x, start_x + length_m, half_blend));
}

double GroundProfile::slopeAt(double x) const
{
  const double half_blend = 0.5 * blend_length_m;
  return grade * (ramp(x, start_x, half_blend) - ramp(x, start_x + length_m, half_blend));
}

PoseFunction carDrive(const CarDriveOptions& options)
{
  return [options](double t)
  {
    const double omega = 2.0 * kPi / options.weave_period_s;
    const double x = options.start_x + options.speed * t;
    const double y = options.weave_amplitude_m * std::sin(omega * t);
    const double heading = std::atan2(options.weave_amplitude_m * omega * std::cos(omega * t), options.speed);
    const double pitch = std::atan(options.ground.slopeAt(x));
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.linear() = headingPitch(heading, pitch);
    pose.translation() = Eigen::Vector3d(x, y, options.ground.heightAt(x) + options.height_m);
    return pose;
  };
}

PoseFunction carDrive(double speed, const GroundProfile& ground)
{
  CarDriveOptions options;
  options.speed = speed;
  options.ground = ground;
  return carDrive(options);
}

double handHeldYawRate(const HandHeldOptions& options, double t)
{
  if (!options.burst_times_s.empty())
  {
    return sumOfTimedBursts(options, t, burstRate);
  }
  const double since_first = t - options.first_burst_s;
  if (since_first < 0.0)
  {
    return 0.0;
  }
  const long index = static_cast<long>(std::floor(since_first / options.burst_interval_s));
  const double tau = since_first - static_cast<double>(index) * options.burst_interval_s;
  return burstSign(index) * options.burst_rate_rad_s * burstRate(tau, options.burst_duration_s, options.burst_edge_s);
}

double handHeldYaw(const HandHeldOptions& options, double t)
{
  if (!options.burst_times_s.empty())
  {
    return sumOfTimedBursts(options, t, burstAngle);
  }
  const double since_first = t - options.first_burst_s;
  if (since_first < 0.0)
  {
    return 0.0;
  }
  const long index = static_cast<long>(std::floor(since_first / options.burst_interval_s));
  const double tau = since_first - static_cast<double>(index) * options.burst_interval_s;
  const double turn = options.burst_rate_rad_s * options.burst_duration_s;
  return turn * completedTurns(index) +
         burstSign(index) * options.burst_rate_rad_s * burstAngle(tau, options.burst_duration_s, options.burst_edge_s);
}

PoseFunction handHeld(const HandHeldOptions& options)
{
  return [options](double t)
  {
    // Bobbing and sway follow the steps: they pause while the walker stands still.
    const double walked = walkedTime(options, t);
    const double x = options.start_x + options.speed * walked;
    const double bob_phase = 2.0 * kPi * options.bob_frequency_hz * walked;
    // Roll sways once per two steps (half the bobbing frequency).
    const double roll = options.roll_amplitude_rad * std::sin(0.5 * bob_phase);
    const double z = options.ground.heightAt(x) + options.height_m + options.bob_amplitude_m * std::sin(bob_phase);
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.linear() = (Eigen::AngleAxisd(handHeldYaw(options, t), Eigen::Vector3d::UnitZ()) *
                     Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
                        .toRotationMatrix();
    if (options.pitch_amplitude_rad != 0.0)
    {
      const double pitch = options.pitch_amplitude_rad * std::cos(0.5 * bob_phase);
      pose.linear() = pose.linear() * Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()).toRotationMatrix();
    }
    pose.translation() = Eigen::Vector3d(x, 0.0, z);
    return pose;
  };
}

PoseFunction handHeld(double speed, const GroundProfile& ground)
{
  HandHeldOptions options;
  options.speed = speed;
  options.ground = ground;
  return handHeld(options);
}

double handHeldDistance(const HandHeldOptions& options, double t)
{
  return options.speed * walkedTime(options, t);
}

double handHeldSpeed(const HandHeldOptions& options, double t)
{
  double start_factor = 1.0;
  if (options.start_rest_s > 0.0 && t < options.start_rest_s + options.stop_edge_s)
  {
    start_factor = t <= options.start_rest_s ? 0.0 : burstRate(t - options.start_rest_s, 1e9, options.stop_edge_s);
  }
  const double since_first = t - options.first_stop_s;
  if (options.stop_interval_s <= 0.0 || since_first < 0.0)
  {
    return options.speed * start_factor;
  }
  const long index = static_cast<long>(std::floor(since_first / options.stop_interval_s));
  const double tau = since_first - static_cast<double>(index) * options.stop_interval_s;
  return options.speed * start_factor *
         (1.0 - burstRate(tau, options.stop_edge_s + options.stop_still_s, options.stop_edge_s));
}

HandHeldOptions handHeldBurstsOptions()
{
  HandHeldOptions options;
  options.burst_rate_rad_s = kBurstsRateDegS * kDegToRad;
  options.burst_interval_s = kBurstsInterval;
  options.stop_interval_s = kBurstsStopInterval;
  options.first_stop_s = kBurstsFirstStop;
  return options;
}

Eigen::Vector2d turnDisplacement(double turn_angle_rad, double turn_length_m)
{
  return integrateTurn(turn_angle_rad, turn_length_m, 0.0, turn_length_m, 2 * kTurnNodes);
}

double turnWalkHeading(const TurnWalkOptions& options, double distance_m)
{
  return options.start_heading +
         turnHeading(options.turn_angle_rad, options.turn_length_m, distance_m - options.turn_start_m);
}

TurnWalkOptions officeTurnWalk(const OfficeOptions& office)
{
  TurnWalkOptions options;
  options.start_xy = Eigen::Vector2d(kOfficeStartX, 0.0);
  options.start_heading = 0.0;
  const Eigen::Vector2d turn = turnDisplacement(options.turn_angle_rad, options.turn_length_m);
  options.turn_start_m = office.turnCenterX() - turn.x() - kOfficeStartX;
  return options;
}

PoseFunction handHeldTurn(const TurnWalkOptions& options)
{
  // Positions along the turn (relative to its start, in the frame of the initial heading), tabulated.
  auto table = std::make_shared<std::vector<Eigen::Vector2d>>();
  table->reserve(kTurnNodes + 1);
  table->push_back(Eigen::Vector2d::Zero());
  const double node = options.turn_length_m / kTurnNodes;
  for (int i = 0; i < kTurnNodes; ++i)
  {
    table->push_back(table->back() + integrateTurn(options.turn_angle_rad, options.turn_length_m, i * node,
                                                   (i + 1) * node, kTurnSubsteps));
  }
  return [options, table, node](double t)
  {
    const double d = options.speed * t;
    const Eigen::Rotation2Dd initial(options.start_heading);
    const Eigen::Vector2d turn_start = options.start_xy + options.turn_start_m * direction(options.start_heading);
    Eigen::Vector2d xy;
    if (d <= options.turn_start_m)
    {
      xy = options.start_xy + d * direction(options.start_heading);
    }
    else if (d < options.turn_start_m + options.turn_length_m)
    {
      const double u = (d - options.turn_start_m) / node;
      const int i = std::min(static_cast<int>(u), kTurnNodes - 1);
      const double f = u - i;
      xy = turn_start + initial * ((1.0 - f) * (*table)[i] + f * (*table)[i + 1]);
    }
    else
    {
      xy = turn_start + initial * table->back() +
           (d - options.turn_start_m - options.turn_length_m) *
               direction(options.start_heading + options.turn_angle_rad);
    }
    return swayedPose(xy, turnWalkHeading(options, d), t,
                      WalkSway{ options.height_m, options.bob_amplitude_m, options.bob_frequency_hz,
                                options.roll_amplitude_rad, options.yaw_sway_rad });
  };
}

Eigen::Isometry3d swayedPose(const Eigen::Vector2d& xy, double heading, double t, const WalkSway& sway)
{
  const double bob_phase = 2.0 * kPi * sway.bob_frequency_hz * t;
  const double roll = sway.roll_amplitude_rad * std::sin(0.5 * bob_phase);
  const double yaw = heading + sway.yaw_sway_rad * std::cos(0.5 * bob_phase);
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
                      .toRotationMatrix();
  pose.translation() = Eigen::Vector3d(xy.x(), xy.y(), sway.height_m + sway.bob_amplitude_m * std::sin(bob_phase));
  return pose;
}

HandHeldOptions stairsWalkOptions(const StairsOptions& stairs)
{
  HandHeldOptions options;
  options.speed = kStairsSpeed;
  options.start_x = kStairsStartX;
  options.bob_amplitude_m = kStairsBob;
  options.burst_rate_rad_s = kStairsBurstRateDegS * kDegToRad;
  options.ground = stairsProfile(stairs);
  return options;
}

PoseFunction straight(const StraightOptions& options)
{
  return [options](double t)
  {
    const double x = options.start_x + options.speed * t;
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.linear() = headingPitch(0.0, std::atan(options.ground.slopeAt(x)));
    pose.translation() = Eigen::Vector3d(x, 0.0, options.ground.heightAt(x) + options.height_m);
    return pose;
  };
}

PoseFunction straight(double speed, const GroundProfile& ground)
{
  StraightOptions options;
  options.speed = speed;
  options.ground = ground;
  return straight(options);
}

std::vector<double> publishedSweepStarts(double duration_s, double period_s, int keep_every)
{
  if (!(period_s > 0.0) || keep_every < 1)
  {
    throw std::invalid_argument("publishedSweepStarts: period must be positive and keep_every >= 1");
  }
  const long sweeps = static_cast<long>(std::floor(duration_s / period_s + 1e-9));
  std::vector<double> starts;
  for (long k = 0; k < sweeps; k += keep_every)
  {
    starts.push_back(static_cast<double>(k) * period_s);
  }
  return starts;
}

}  // namespace sim
}  // namespace aloam
