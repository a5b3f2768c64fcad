// Trajectories and extra scenes of the simulator: smoothness, hand-held yaw bursts, the car inside
// the street and on the hill, determinism of the simulated sweeps.
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <vector>

#include <gtest/gtest.h>

#include "aloam_nodelet/core/sensor_model.h"
#include "aloam_nodelet/sim/raycaster.h"
#include "aloam_nodelet/sim/scenes_extra.h"
#include "aloam_nodelet/sim/trajectories.h"

namespace
{
constexpr double kPi = 3.14159265358979323846;
constexpr double kStep = 0.005;    // s, finite-difference step
constexpr double kHorizon = 30.0;  // s of trajectory checked
constexpr double kCarHalfWidth = 1.0;
constexpr unsigned kSeed = 11;

double rotationAngle(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b)
{
  return Eigen::AngleAxisd(a.linear().transpose() * b.linear()).angle();
}

/// Maximum speed, acceleration, angular rate and angular acceleration by finite differences.
struct Derivatives
{
  double max_speed = 0.0;
  double max_acceleration = 0.0;
  double max_rate = 0.0;
  double max_angular_acceleration = 0.0;
};

Derivatives measure(const aloam::sim::PoseFunction& pose_at)
{
  Derivatives d;
  for (double t = kStep; t < kHorizon; t += kStep)
  {
    const Eigen::Isometry3d before = pose_at(t - kStep);
    const Eigen::Isometry3d now = pose_at(t);
    const Eigen::Isometry3d after = pose_at(t + kStep);
    const Eigen::Vector3d velocity = (after.translation() - before.translation()) / (2.0 * kStep);
    const Eigen::Vector3d acceleration =
        (after.translation() - 2.0 * now.translation() + before.translation()) / (kStep * kStep);
    const double rate_in = rotationAngle(before, now) / kStep;
    const double rate_out = rotationAngle(now, after) / kStep;
    d.max_speed = std::max(d.max_speed, velocity.norm());
    d.max_acceleration = std::max(d.max_acceleration, acceleration.norm());
    d.max_rate = std::max(d.max_rate, std::max(rate_in, rate_out));
    d.max_angular_acceleration = std::max(d.max_angular_acceleration, std::abs(rate_out - rate_in) / kStep);
    EXPECT_TRUE(now.matrix().allFinite());
  }
  return d;
}

/// Half width of the street (curb to centerline) of a scene built by urbanStreet*: the innermost
/// edge of the sidewalk slabs.
double streetHalfWidth(const aloam::sim::Scene& scene)
{
  double half_width = 1e9;
  for (const auto& primitive : scene.primitives())
  {
    if (primitive.surface_class != aloam::sim::SurfaceClass::Ground ||
        !std::holds_alternative<aloam::sim::OrientedBox>(primitive.shape))
    {
      continue;
    }
    const aloam::sim::Aabb box = aloam::sim::shapeBounds(primitive.shape);
    half_width = std::min(half_width, box.min.y() > 0.0 ? box.min.y() : -box.max.y());
  }
  return half_width;
}

bool sameCloud(const aloam::Cloud& a, const aloam::Cloud& b)
{
  if (a.size() != b.size())
  {
    return false;
  }
  for (std::size_t i = 0; i < a.size(); ++i)
  {
    const auto& p = a.points[i];
    const auto& q = b.points[i];
    if (p.x != q.x || p.y != q.y || p.z != q.z || p.intensity != q.intensity || p.time != q.time || p.ring != q.ring)
    {
      return false;
    }
  }
  return true;
}
}  // namespace

TEST(GroundProfile, ContinuousHeightAndSlope)
{
  const aloam::sim::GroundProfile hill;
  EXPECT_DOUBLE_EQ(hill.heightAt(hill.start_x - hill.blend_length_m), 0.0);
  EXPECT_NEAR(hill.heightAt(hill.start_x + hill.length_m + hill.blend_length_m), hill.rise(), 1e-12);
  EXPECT_NEAR(hill.slopeAt(hill.start_x + 0.5 * hill.length_m), hill.grade, 1e-12);
  const double h = 1e-4;
  for (double x = -20.0; x < 150.0; x += 0.37)
  {
    const double numeric = (hill.heightAt(x + h) - hill.heightAt(x - h)) / (2.0 * h);
    EXPECT_NEAR(numeric, hill.slopeAt(x), 1e-6) << "x = " << x;
    EXPECT_LE(std::abs(hill.slopeAt(x + 0.1) - hill.slopeAt(x)), 1.5 * hill.grade * 0.1 / hill.blend_length_m + 1e-12);
  }
  EXPECT_DOUBLE_EQ(aloam::sim::GroundProfile::flat().heightAt(100.0), 0.0);
}

TEST(Trajectories, SmoothFiniteDifferences)
{
  const aloam::sim::GroundProfile hill;
  const Derivatives car = measure(aloam::sim::carDrive(10.0, hill));
  EXPECT_LT(car.max_speed, 10.5);
  EXPECT_GT(car.max_speed, 9.9);
  EXPECT_LT(car.max_acceleration, 2.0);
  EXPECT_LT(car.max_rate, 0.2);
  EXPECT_LT(car.max_angular_acceleration, 1.0);

  const Derivatives walk = measure(aloam::sim::handHeld(1.4, hill));
  EXPECT_LT(walk.max_speed, 1.6);
  EXPECT_LT(walk.max_acceleration, 6.0);  // bobbing: 0.03 m * (2 pi 2 Hz)^2 = 4.7 m/s^2
  EXPECT_LT(walk.max_rate, 1.7);
  EXPECT_LT(walk.max_angular_acceleration, 30.0);  // raised-cosine edges: 90 deg/s in 0.1 s

  const Derivatives line = measure(aloam::sim::straight(5.0));
  EXPECT_NEAR(line.max_speed, 5.0, 1e-6);
  EXPECT_LT(line.max_acceleration, 1e-3);
  EXPECT_LT(line.max_rate, 1e-9);
}

TEST(Trajectories, HandHeldYawBursts)
{
  const aloam::sim::HandHeldOptions options;
  const aloam::sim::PoseFunction pose_at = aloam::sim::handHeld(options);
  const double target = 0.5 * kPi;  // 90 deg/s
  for (int burst = 0; burst < 6; ++burst)
  {
    const double begin = options.first_burst_s + burst * options.burst_interval_s;
    double peak = 0.0;
    double fast_time = 0.0;
    double sign = 0.0;
    for (double t = begin - 0.5; t < begin + 1.0; t += kStep)
    {
      const Eigen::Vector3d heading_a = pose_at(t).linear().col(0);
      const Eigen::Vector3d heading_b = pose_at(t + kStep).linear().col(0);
      const double rate = (std::atan2(heading_b.y(), heading_b.x()) - std::atan2(heading_a.y(), heading_a.x())) / kStep;
      peak = std::max(peak, std::abs(rate));
      if (std::abs(rate) > 0.5 * target)
      {
        fast_time += kStep;
        sign = rate > 0.0 ? 1.0 : -1.0;
      }
    }
    EXPECT_NEAR(peak, target, 0.05 * target) << "burst " << burst;
    EXPECT_NEAR(fast_time, options.burst_duration_s, 0.03) << "burst " << burst;
    // Left, right, right, left.
    EXPECT_EQ(sign, (burst % 4 == 0 || burst % 4 == 3) ? 1.0 : -1.0) << "burst " << burst;
    // Between bursts the yaw is constant.
    EXPECT_NEAR(aloam::sim::handHeldYawRate(options, begin + 0.5 * options.burst_interval_s + 0.5), 0.0, 1e-12);
  }
  for (double t = 0.0; t < kHorizon; t += 0.05)
  {
    EXPECT_LE(std::abs(aloam::sim::handHeldYaw(options, t)), 0.25 * kPi + 1e-9);
    const double z = pose_at(t).translation().z();
    EXPECT_NEAR(z, options.height_m, options.bob_amplitude_m + 1e-9);
  }
}

TEST(Trajectories, CarStaysInStreetAndFollowsHill)
{
  const aloam::sim::GroundProfile hill;
  aloam::sim::CarDriveOptions options;
  options.ground = hill;
  const aloam::sim::PoseFunction pose_at = aloam::sim::carDrive(options);
  const double length = options.start_x + options.speed * kHorizon + 50.0;
  const aloam::sim::Scene scene = aloam::sim::urbanStreetWithHill(kSeed, length, hill);
  const double half_width = streetHalfWidth(scene);
  ASSERT_GE(half_width, 6.0);
  ASSERT_LE(half_width, 8.0);
  bool saw_ramp = false;
  for (double t = 0.0; t < kHorizon; t += 0.1)
  {
    const Eigen::Isometry3d pose = pose_at(t);
    const Eigen::Vector3d p = pose.translation();
    EXPECT_LT(std::abs(p.y()) + kCarHalfWidth, half_width) << "t = " << t;
    // The scene's ground is under the sensor at the right height.
    const auto down = scene.intersect(p, -Eigen::Vector3d::UnitZ(), 10.0);
    ASSERT_TRUE(down.has_value()) << "t = " << t;
    EXPECT_EQ(down->surface_class, aloam::sim::SurfaceClass::Ground);
    EXPECT_NEAR(down->distance, options.height_m, 0.01) << "t = " << t;
    // Pitch follows the slope: the forward axis climbs at the ground's grade.
    const Eigen::Vector3d forward = pose.linear().col(0);
    const double climb = forward.z() / forward.head<2>().norm();
    EXPECT_NEAR(climb, hill.slopeAt(p.x()), 1e-9);
    if (std::abs(hill.slopeAt(p.x()) - hill.grade) < 1e-12)
    {
      saw_ramp = true;
      EXPECT_NEAR(down->normal.z(), 1.0 / std::sqrt(1.0 + hill.grade * hill.grade), 1e-6);
    }
    // Nothing but the ground within 2 m below / 1 m sideways of the car's roof (clear path).
    for (const double side : { -1.0, 1.0 })
    {
      const auto lateral = scene.intersect(p, side * pose.linear().col(1), kCarHalfWidth);
      EXPECT_FALSE(lateral.has_value()) << "t = " << t;
    }
  }
  EXPECT_TRUE(saw_ramp);
  EXPECT_NEAR(pose_at(kHorizon).translation().z(), hill.rise() + options.height_m, 1e-9);
}

TEST(Scenes, CorridorAndFieldAroundTheirTrajectories)
{
  const aloam::sim::CorridorOptions corridor_options;
  const aloam::sim::Scene corridor = aloam::sim::corridorScene(kSeed, corridor_options);
  const aloam::sim::PoseFunction walk = aloam::sim::handHeld(aloam::sim::HandHeldOptions());
  for (double t = 0.0; t < 60.0; t += 0.25)
  {
    const Eigen::Vector3d p = walk(t).translation();
    ASSERT_LT(p.x(), corridor_options.length_m);
    for (const double side : { -1.0, 1.0 })
    {
      const auto wall = corridor.intersect(p, Eigen::Vector3d(0.0, side, 0.0), 10.0);
      ASSERT_TRUE(wall.has_value());
      EXPECT_GE(wall->distance, 0.5 * corridor_options.width_m - 1e-9);
      EXPECT_LE(wall->distance, 0.5 * corridor_options.width_m + 0.6 + 1e-9);
    }
    const auto up = corridor.intersect(p, Eigen::Vector3d::UnitZ(), 10.0);
    ASSERT_TRUE(up.has_value());
    EXPECT_LE(up->distance + p.z(), corridor_options.height_m + 1e-9);
  }
  const aloam::sim::Scene field = aloam::sim::openFieldScene(kSeed, 300.0);
  EXPECT_LE(field.size(), 8U);
  EXPECT_EQ(field.countClass(aloam::sim::SurfaceClass::Ground), 1);
}

TEST(Scenes, SameSeedGivesIdenticalSweeps)
{
  const auto sensor = aloam::SensorModel::fromPreset("VLP16");
  ASSERT_TRUE(sensor.has_value());
  const aloam::sim::GroundProfile hill;
  aloam::sim::ScanOptions options;
  options.range_noise_sigma = 0.02;
  options.dropout_probability = 0.05;
  options.seed = 1234;
  const double start = 2.5;  // on the ramp's first vertical curve
  const auto sweep = [&](unsigned scene_seed)
  {
    const aloam::sim::Scene scene = aloam::sim::urbanStreetWithHill(scene_seed, 200.0, hill);
    const aloam::sim::PoseFunction pose_at = aloam::sim::carDrive(10.0, hill);
    return aloam::sim::scan(
        scene, *sensor, [&](double t) { return pose_at(start + t); }, options);
  };
  const aloam::Cloud a = sweep(kSeed);
  const aloam::Cloud b = sweep(kSeed);
  ASSERT_GT(a.size(), 10000U);
  EXPECT_TRUE(sameCloud(a, b));
  EXPECT_FALSE(sameCloud(a, sweep(kSeed + 1)));

  const aloam::sim::Scene corridor_a = aloam::sim::corridorScene(kSeed);
  const aloam::sim::Scene corridor_b = aloam::sim::corridorScene(kSeed);
  const aloam::sim::PoseFunction walk = aloam::sim::handHeld(aloam::sim::HandHeldOptions());
  const auto walk_at = [&](double t) { return walk(3.9 + t); };
  EXPECT_TRUE(sameCloud(aloam::sim::scan(corridor_a, *sensor, walk_at, options),
                        aloam::sim::scan(corridor_b, *sensor, walk_at, options)));
}

TEST(Trajectories, BurstsReach120DegPerSecondAndStopsStandStill)
{
  const aloam::sim::HandHeldOptions options = aloam::sim::handHeldBurstsOptions();
  const aloam::sim::PoseFunction pose_at = aloam::sim::handHeld(options);
  const double horizon = 20.0;
  double peak = 0.0;
  for (double t = 0.0; t < horizon; t += kStep)
  {
    const Eigen::Vector3d heading_a = pose_at(t).linear().col(0);
    const Eigen::Vector3d heading_b = pose_at(t + kStep).linear().col(0);
    peak = std::max(
        peak, std::abs(std::atan2(heading_b.y(), heading_b.x()) - std::atan2(heading_a.y(), heading_a.x())) / kStep);
    // The analytic speed agrees with the motion.
    const double moved = (pose_at(t + kStep).translation().x() - pose_at(t - kStep).translation().x()) / (2.0 * kStep);
    EXPECT_NEAR(aloam::sim::handHeldSpeed(options, t), moved, 1e-3) << "t = " << t;
  }
  EXPECT_NEAR(peak, 120.0 * kPi / 180.0, 0.05 * 120.0 * kPi / 180.0);

  int stops = 0;
  for (double start = options.first_stop_s; start + options.stop_still_s + 2.0 * options.stop_edge_s < horizon;
       start += options.stop_interval_s, ++stops)
  {
    const double still_from = start + options.stop_edge_s;
    const double still_to = still_from + options.stop_still_s;
    const Eigen::Isometry3d standing = pose_at(still_from);
    for (double t = still_from; t <= still_to; t += 0.01)
    {
      // Completely still: no translation (no bobbing either) and no rotation.
      EXPECT_LT((pose_at(t).translation() - standing.translation()).norm(), 1e-9) << "t = " << t;
      EXPECT_LT(rotationAngle(pose_at(t), standing), 1e-9) << "t = " << t;
      EXPECT_EQ(aloam::sim::handHeldSpeed(options, t), 0.0) << "t = " << t;
    }
    // Walking at full speed before and after.
    for (const double t : { start - 0.2, still_to + options.stop_edge_s + 0.2 })
    {
      const double v = (pose_at(t + kStep).translation().x() - pose_at(t - kStep).translation().x()) / (2.0 * kStep);
      EXPECT_NEAR(v, options.speed, 1e-6) << "t = " << t;
    }
  }
  EXPECT_GE(stops, 2);
  // Each stop costs the distance of (edge + still) seconds of walking.
  const double lost = options.stop_edge_s + options.stop_still_s;
  const double t_after = options.first_stop_s + options.stop_interval_s - 0.5;
  EXPECT_NEAR(aloam::sim::handHeldDistance(options, t_after), options.speed * (t_after - lost), 1e-9);
  // Without stops the walk is unchanged.
  EXPECT_DOUBLE_EQ(aloam::sim::handHeldDistance(aloam::sim::HandHeldOptions(), 7.0), 1.4 * 7.0);
  const Derivatives walk = measure(pose_at);
  EXPECT_LT(walk.max_speed, options.speed + 0.2);
  EXPECT_LT(walk.max_acceleration, 11.0);  // bobbing 4.7 m/s^2 plus braking 1.4 m/s in 0.4 s (raised cosine)
}

TEST(Trajectories, OfficeTurnWalkTurnsTheCornerInsideTheL)
{
  const aloam::sim::OfficeOptions office;
  const aloam::sim::TurnWalkOptions walk = aloam::sim::officeTurnWalk(office);
  const aloam::sim::PoseFunction pose_at = aloam::sim::handHeldTurn(walk);
  const double half_width = 0.5 * office.width_m;
  const Eigen::Vector2d turn = aloam::sim::turnDisplacement(walk.turn_angle_rad, walk.turn_length_m);
  EXPECT_NEAR(turn.x(), turn.y(), 1e-6);  // the smoothstep turn is symmetric
  EXPECT_GT(turn.x(), 0.5 * walk.turn_length_m);
  EXPECT_NEAR(pose_at(0.0).translation().head<2>().norm(), walk.start_xy.norm(), 1e-9);

  const double turn_begin = walk.turn_start_m / walk.speed;
  const double turn_end = (walk.turn_start_m + walk.turn_length_m) / walk.speed;
  EXPECT_GT(turn_begin, 5.0);  // a walk along the first corridor first
  // Before the turn: on the first centerline heading +x; after it: on the second centerline heading +y.
  for (double t = 0.0; t < turn_begin; t += 0.1)
  {
    EXPECT_NEAR(pose_at(t).translation().y(), 0.0, 1e-9);
  }
  const double end = (office.secondEndY() - 1.0 - turn.y()) / walk.speed + turn_end;
  for (double t = turn_end; t < end; t += 0.1)
  {
    const Eigen::Isometry3d pose = pose_at(t);
    EXPECT_NEAR(pose.translation().x(), office.turnCenterX(), 1e-4) << "t = " << t;
    const Eigen::Vector3d forward = pose.linear().col(0);
    EXPECT_NEAR(std::atan2(forward.y(), forward.x()), 0.5 * kPi, walk.yaw_sway_rad + 0.01) << "t = " << t;
  }
  EXPECT_NEAR(aloam::sim::turnWalkHeading(walk, 1e3) - aloam::sim::turnWalkHeading(walk, 0.0), 0.5 * kPi, 1e-12);

  // The walker stays clear of the walls, doors and cabinets all the way (the scene's clutter and openings
  // depend on the seed, the path does not).
  for (const unsigned seed : { 1U, 2U, 3U })
  {
    const aloam::sim::Scene scene = aloam::sim::officeScene(seed, office);
    double clearance = 1e9;
    for (double t = 0.0; t < end; t += 0.05)
    {
      const Eigen::Vector3d p = pose_at(t).translation();
      for (int k = 0; k < 16; ++k)
      {
        const double a = 2.0 * kPi * k / 16;
        const auto hit = scene.intersect(p, Eigen::Vector3d(std::cos(a), std::sin(a), 0.0), 5.0);
        if (hit)
        {
          clearance = std::min(clearance, hit->distance);
        }
      }
    }
    EXPECT_GT(clearance, 0.6) << "seed " << seed;
    EXPECT_LT(clearance, half_width) << "seed " << seed;
  }
  const Derivatives d = measure(pose_at);
  EXPECT_LT(d.max_speed, walk.speed + 0.4);    // bobbing adds a little vertical speed
  EXPECT_GT(d.max_rate, 60.0 * kPi / 180.0);   // the corner is turned briskly ...
  EXPECT_LT(d.max_rate, 100.0 * kPi / 180.0);  // ... but like a person
}

TEST(Trajectories, StairsWalkClimbsTheFlight)
{
  const aloam::sim::StairsOptions stairs;
  const aloam::sim::HandHeldOptions options = aloam::sim::stairsWalkOptions(stairs);
  const aloam::sim::PoseFunction pose_at = aloam::sim::handHeld(options);
  const aloam::sim::Scene scene = aloam::sim::stairsScene(kSeed, stairs);
  const double duration = 15.0;
  const Eigen::Vector3d first = pose_at(0.0).translation();
  const Eigen::Vector3d last = pose_at(duration).translation();
  EXPECT_LT(first.x(), -1.0);                                      // starts on the bottom landing
  EXPECT_GT(last.x(), stairs.run() + 0.5);                         // ends on the top landing
  EXPECT_LT(last.x(), stairs.run() + stairs.top_landing_m - 1.0);  // short of its end wall
  EXPECT_NEAR(last.z() - first.z(), stairs.totalRise(), 2.0 * options.bob_amplitude_m);
  double previous_z = first.z();
  double x_low = 0.0;   // where 10 % of the climb is done
  double x_high = 0.0;  // where 90 % is done
  for (double t = 0.0; t <= duration; t += 0.05)
  {
    const Eigen::Vector3d p = pose_at(t).translation();
    const auto down = scene.intersect(p, -Eigen::Vector3d::UnitZ(), 5.0);
    ASSERT_TRUE(down.has_value()) << "t = " << t;
    EXPECT_EQ(down->surface_class, aloam::sim::SurfaceClass::Ground) << "t = " << t;
    EXPECT_GT(down->distance, 1.2) << "t = " << t;
    EXPECT_LT(down->distance, 1.8) << "t = " << t;
    EXPECT_GT(p.z(), previous_z - 2.0 * options.bob_amplitude_m) << "t = " << t;  // never down the stairs
    previous_z = std::max(previous_z, p.z());
    const double climbed = (p.z() - first.z()) / stairs.totalRise();
    x_low = climbed < 0.1 ? p.x() : x_low;
    x_high = climbed < 0.9 ? p.x() : x_high;
  }
  // About 3 m up over a few metres: the flight's run (4.5 m) at its mean grade.
  EXPECT_LT(x_high - x_low, stairs.run());
  EXPECT_GT(x_high - x_low, 0.6 * stairs.run());
}

TEST(Trajectories, PublishedSweepStartsOfAThrottledTopic)
{
  const double period = 0.1;
  for (const int keep_every : { 1, 2, 5 })
  {
    const std::vector<double> starts = aloam::sim::publishedSweepStarts(8.0, period, keep_every);
    ASSERT_EQ(starts.size(), static_cast<std::size_t>((80 + keep_every - 1) / keep_every)) << keep_every;
    EXPECT_EQ(starts.front(), 0.0);
    for (std::size_t i = 1; i < starts.size(); ++i)
    {
      EXPECT_NEAR(starts[i] - starts[i - 1], keep_every * period, 1e-12);
    }
    EXPECT_LE(starts.back() + period, 8.0 + 1e-9);
  }
  EXPECT_EQ(aloam::sim::publishedSweepStarts(0.05, period, 1).size(), 0U);
  EXPECT_EQ(aloam::sim::publishedSweepStarts(0.75, period, 2).size(), 4U);  // sweeps 0, 2, 4, 6
  EXPECT_THROW(aloam::sim::publishedSweepStarts(8.0, period, 0), std::invalid_argument);
  EXPECT_THROW(aloam::sim::publishedSweepStarts(8.0, 0.0, 1), std::invalid_argument);
}
