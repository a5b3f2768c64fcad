#include "aloam_nodelet/sim/trajectories.h"

#include <algorithm>
#include <cmath>

namespace aloam
{
namespace sim
{
namespace
{
constexpr double kPi = 3.14159265358979323846;
constexpr int kBurstPatternLength = 4;

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
    const double x = options.start_x + options.speed * t;
    const double bob_phase = 2.0 * kPi * options.bob_frequency_hz * t;
    // Roll sways once per two steps (half the bobbing frequency).
    const double roll = options.roll_amplitude_rad * std::sin(0.5 * bob_phase);
    const double z = options.ground.heightAt(x) + options.height_m + options.bob_amplitude_m * std::sin(bob_phase);
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.linear() = (Eigen::AngleAxisd(handHeldYaw(options, t), Eigen::Vector3d::UnitZ()) *
                     Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
                        .toRotationMatrix();
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

}  // namespace sim
}  // namespace aloam
