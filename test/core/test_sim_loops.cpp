// Looping scene families: a draw is a function of (family, seed), the drawn values stay in their ranges,
// the motion is smooth and really comes back to earlier places (loop_block, loop_eight, loop_floor, the
// revisiting loop_repetitive draws) or never does (the other loop_repetitive draws), the identical blocks
// of loop_repetitive are identical, and trueRevisits finds the returns.
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "aloam_nodelet/sim/families.h"
#include "aloam_nodelet/sim/loops.h"

namespace
{
using aloam::sim::Family;
using aloam::sim::FamilyDraw;

constexpr double kPi = 3.14159265358979323846;
constexpr double kLoopDuration = 90.0;  // s, long enough for every family to loop
constexpr double kFloorDuration = 90.0;
constexpr double kSweep = 0.1;  // s
constexpr unsigned kSeeds = 60;
const Family kLoopFamilies[] = { Family::LoopBlock, Family::LoopEight, Family::LoopFloor, Family::LoopRepetitive };

double wrapAngle(double a)
{
  return std::atan2(std::sin(a), std::cos(a));
}

double yawOf(const Eigen::Isometry3d& pose)
{
  const Eigen::Vector3d x = pose.linear().col(0);
  return std::atan2(x.y(), x.x());
}

/// Nearest distance of the pose at time t to any pose more than min_gap_s earlier.
double closestEarlier(const aloam::sim::PoseFunction& motion, double t, double min_gap_s)
{
  const Eigen::Vector3d p = motion(t).translation();
  double best = std::numeric_limits<double>::infinity();
  for (double s = 0.0; s < t - min_gap_s; s += 0.02)
  {
    best = std::min(best, (motion(s).translation() - p).norm());
  }
  return best;
}

double rayDistance(const aloam::sim::Scene& scene, const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                   double range)
{
  const auto hit = scene.intersect(origin, direction, range);
  return hit ? hit->distance : std::numeric_limits<double>::infinity();
}

TEST(SimLoops, NamesAndDeterminismBySeed)
{
  for (const Family family : kLoopFamilies)
  {
    const std::string name = aloam::sim::familyName(family);
    ASSERT_EQ(name.rfind("loop_", 0), 0u) << name;
    ASSERT_EQ(aloam::sim::familyFromName(name), family);
    for (unsigned seed = 0; seed < 4; ++seed)
    {
      const FamilyDraw a = aloam::sim::drawFamily(family, seed, kLoopDuration);
      const FamilyDraw b = aloam::sim::drawFamily(family, seed, kLoopDuration);
      EXPECT_EQ(a.describe(), b.describe());
      EXPECT_NE(a.describe(), aloam::sim::drawFamily(family, seed + 1, kLoopDuration).describe());
      const aloam::sim::Scene scene_a = aloam::sim::familyScene(a);
      const aloam::sim::Scene scene_b = aloam::sim::familyScene(b);
      ASSERT_EQ(scene_a.size(), scene_b.size()) << name;
      // Same primitives: the same answers to a fan of rays.
      const Eigen::Vector3d origin = aloam::sim::familyMotion(a)(0.0).translation();
      for (int k = 0; k < 36; ++k)
      {
        const Eigen::Vector3d dir(std::cos(k * 0.17), std::sin(k * 0.17), -0.05 + 0.01 * (k % 10));
        EXPECT_EQ(rayDistance(scene_a, origin, dir, 150.0), rayDistance(scene_b, origin, dir, 150.0)) << name;
      }
      for (const double t : { 0.0, 17.3, kLoopDuration })
      {
        EXPECT_TRUE(aloam::sim::familyMotion(a)(t).isApprox(aloam::sim::familyMotion(b)(t), 0.0)) << name << " " << t;
      }
    }
  }
}

TEST(SimLoops, DrawnValuesStayInTheirRanges)
{
  for (const Family family : kLoopFamilies)
  {
    const std::string name = aloam::sim::familyName(family);
    int revisiting = 0;
    for (unsigned seed = 0; seed < 200; ++seed)
    {
      const FamilyDraw draw = aloam::sim::drawFamily(family, seed, kLoopDuration);
      ASSERT_EQ(draw.motion, aloam::sim::MotionKind::Path);
      for (const aloam::sim::DrawnParameter& p : draw.parameters)
      {
        EXPECT_GE(p.value, p.lo) << name << " seed " << seed << " " << p.key;
        EXPECT_LE(p.value, p.hi) << name << " seed " << seed << " " << p.key;
      }
      const double speed = draw.path.speed;
      if (family == Family::LoopFloor)
      {
        EXPECT_GE(speed, 1.2);
        EXPECT_LE(speed, 1.5);
      }
      else
      {
        EXPECT_GE(speed, 6.0);
        EXPECT_LE(speed, 10.0);
        EXPECT_DOUBLE_EQ(draw.path.height_m, 1.8);
      }
      if (family == Family::LoopBlock)
      {
        // 90 s at 6-10 m/s: the block's size leaves 1.5-2 laps.
        EXPECT_GE(*draw.parameter("laps"), 1.5 - 1e-9) << seed;
        EXPECT_LE(*draw.parameter("laps"), 2.3) << seed;  // rounded corners shorten a lap a little
        EXPECT_GE(*draw.parameter("perimeter_m"), 200.0);
        EXPECT_LE(*draw.parameter("perimeter_m"), 600.0);
      }
      if (family == Family::LoopEight)
      {
        EXPECT_GE(*draw.parameter("laps"), 1.0) << seed;
      }
      if (family == Family::LoopFloor)
      {
        EXPECT_GE(*draw.parameter("laps"), 1.2 - 1e-9) << seed;
        EXPECT_LE(*draw.parameter("laps"), 1.6) << seed;
        EXPECT_GE(draw.ring_floor.width_m, 1.8);
        EXPECT_LE(draw.ring_floor.width_m, 3.0);
      }
      if (family == Family::LoopRepetitive)
      {
        EXPECT_TRUE(draw.city.identical_blocks);
        EXPECT_GE(draw.block_period_m, 50.0);
        EXPECT_LE(draw.block_period_m, 80.0);
        revisiting += *draw.parameter("revisit") > 0.5 ? 1 : 0;
      }
    }
    if (family == Family::LoopRepetitive)
    {
      EXPECT_GT(revisiting, 60);
      EXPECT_LT(revisiting, 140);
    }
  }
}

TEST(SimLoops, ShortDurationsStillGiveAValidScene)
{
  for (const Family family : kLoopFamilies)
  {
    for (const double duration : { 5.0, 15.0, 300.0 })
    {
      const FamilyDraw draw = aloam::sim::drawFamily(family, 3, duration);
      const aloam::sim::Scene scene = aloam::sim::familyScene(draw);
      const aloam::sim::PoseFunction motion = aloam::sim::familyMotion(draw);
      for (double t = 0.0; t <= duration; t += duration / 20.0)
      {
        const Eigen::Vector3d p = motion(t).translation();
        EXPECT_NEAR(rayDistance(scene, p, -Eigen::Vector3d::UnitZ(), 10.0), p.z(), 0.06)
            << aloam::sim::familyName(family) << " " << duration << " " << t;
      }
    }
  }
}

TEST(SimLoops, MotionIsSmoothAndInFreeSpace)
{
  for (const Family family : kLoopFamilies)
  {
    const std::string name = aloam::sim::familyName(family);
    for (unsigned seed = 0; seed < 6; ++seed)
    {
      const FamilyDraw draw = aloam::sim::drawFamily(family, seed, kLoopDuration);
      const aloam::sim::Scene scene = aloam::sim::familyScene(draw);
      const aloam::sim::PoseFunction motion = aloam::sim::familyMotion(draw);
      const double speed = draw.path.speed;
      const bool walk = family == Family::LoopFloor;
      double previous_rate = 0.0;
      for (double t = kSweep; t <= kLoopDuration; t += kSweep)
      {
        const Eigen::Isometry3d a = motion(t - kSweep);
        const Eigen::Isometry3d b = motion(t);
        const double step = (b.translation() - a.translation()).norm();
        // Constant speed along the path: the lane offset and the sway change it by a few percent at most.
        EXPECT_NEAR(step, speed * kSweep, (walk ? 0.25 : 0.12) * speed * kSweep) << name << " " << seed << " " << t;
        const double rate = wrapAngle(yawOf(b) - yawOf(a)) / kSweep;
        EXPECT_LT(std::abs(rate), (walk ? 150.0 : 80.0) * kPi / 180.0) << name << " " << seed << " " << t;
        // No jumps in the yaw rate between consecutive sweeps.
        if (t > kSweep)
        {
          EXPECT_LT(std::abs(rate - previous_rate), (walk ? 1.2 : 0.35)) << name << " " << seed << " " << t;
        }
        previous_rate = rate;
      }
      // Clear of everything round the sensor (walls, cars, poles) every second.
      for (double t = 0.0; t <= kLoopDuration; t += 1.0)
      {
        const Eigen::Vector3d p = motion(t).translation();
        double nearest = std::numeric_limits<double>::infinity();
        for (int k = 0; k < 24; ++k)
        {
          const double azimuth = 2.0 * kPi * k / 24;
          nearest = std::min(nearest,
                             rayDistance(scene, p, Eigen::Vector3d(std::cos(azimuth), std::sin(azimuth), 0.0), 50.0));
        }
        EXPECT_GT(nearest, walk ? 0.5 : 2.0) << name << " seed " << seed << " t " << t;
        EXPECT_NEAR(rayDistance(scene, p, -Eigen::Vector3d::UnitZ(), 10.0), p.z(), 1e-6) << name << " " << t;
        if (walk)
        {
          EXPECT_LT(rayDistance(scene, p, Eigen::Vector3d::UnitZ(), 10.0), 2.0) << "under the ceiling";
        }
      }
    }
  }
}

TEST(SimLoops, LoopsReturnToEarlierPlaces)
{
  for (const Family family : { Family::LoopBlock, Family::LoopEight, Family::LoopFloor })
  {
    const std::string name = aloam::sim::familyName(family);
    for (unsigned seed = 0; seed < 8; ++seed)
    {
      const double duration = family == Family::LoopFloor ? kFloorDuration : kLoopDuration;
      const FamilyDraw draw = aloam::sim::drawFamily(family, seed, duration);
      const aloam::sim::PoseFunction motion = aloam::sim::familyMotion(draw);
      // The end of the drive is back on ground covered more than 30 s before, within 1 m.
      EXPECT_LT(closestEarlier(motion, duration, 30.0), 1.0) << name << " seed " << seed << " " << draw.describe();
      const std::vector<aloam::sim::Revisit> revisits = aloam::sim::trueRevisits(motion, duration, kSweep);
      ASSERT_FALSE(revisits.empty()) << name << " seed " << seed;
      for (const aloam::sim::Revisit& r : revisits)
      {
        EXPECT_GT(r.later_s - r.earlier_s, 30.0);
        EXPECT_LE(r.distance_m, 2.0);
        EXPECT_TRUE(aloam::sim::isTrueRevisit(motion, r.earlier_s, r.later_s));
      }
      // The first lap's start is revisited: a pair with the earlier time within the first seconds.
      const bool start_revisited =
          std::any_of(revisits.begin(), revisits.end(), [](const aloam::sim::Revisit& r) { return r.earlier_s < 5.0; });
      EXPECT_TRUE(start_revisited) << name << " seed " << seed;
    }
  }
}

TEST(SimLoops, FigureEightCrossesTheMiddleBothWays)
{
  for (unsigned seed = 0; seed < 8; ++seed)
  {
    const FamilyDraw draw = aloam::sim::drawFamily(Family::LoopEight, seed, kLoopDuration);
    const aloam::sim::PoseFunction motion = aloam::sim::familyMotion(draw);
    const Eigen::Vector2d middle(draw.city.street_x[1], draw.city.street_y[1]);
    // Headings when passing within 2 m of the middle crossing during the first lap.
    const aloam::sim::RoundedPath path(draw.path.waypoints, true, draw.path.corner_length_m);
    const double lap = path.length() / draw.path.speed;
    std::vector<double> headings;
    double last_pass = -10.0;
    for (double t = 0.0; t < lap; t += 0.02)
    {
      const Eigen::Isometry3d pose = motion(t);
      if ((pose.translation().head<2>() - middle).norm() < 2.0 && t - last_pass > 5.0)
      {
        headings.push_back(yawOf(pose));
        last_pass = t;
      }
    }
    ASSERT_EQ(headings.size(), 2u) << seed;
    EXPECT_NEAR(std::abs(wrapAngle(headings[1] - headings[0])), 0.5 * kPi, 0.05) << seed;
  }
}

TEST(SimLoops, RepetitiveBlocksAreIdentical)
{
  for (unsigned seed = 0; seed < 4; ++seed)
  {
    const FamilyDraw draw = aloam::sim::drawFamily(Family::LoopRepetitive, seed, kLoopDuration);
    const aloam::sim::Scene scene = aloam::sim::familyScene(draw);
    const double period = draw.block_period_m;
    // From a street point and from its copies one and two periods away (x, y or both), rays hit the same
    // surfaces at the same distances.
    const aloam::sim::PoseFunction motion = aloam::sim::familyMotion(draw);
    for (const double t : { 0.0, 7.0, 13.0 })
    {
      const Eigen::Vector3d p = motion(t).translation();
      // Shifts towards the middle of the grid, so that both points are well inside it.
      const double sx = p.x() < 0.5 * (draw.city.street_x.front() + draw.city.street_x.back()) ? 1.0 : -1.0;
      const double sy = p.y() < 0.5 * (draw.city.street_y.front() + draw.city.street_y.back()) ? 1.0 : -1.0;
      for (const Eigen::Vector3d& shift :
           { Eigen::Vector3d(sx * period, 0, 0), Eigen::Vector3d(0, sy * period, 0),
             Eigen::Vector3d(sx * period, sy * period, 0), Eigen::Vector3d(2 * sx * period, 0, 0) })
      {
        for (int k = 0; k < 72; ++k)
        {
          const double azimuth = 2.0 * kPi * k / 72;
          const Eigen::Vector3d dir(std::cos(azimuth), std::sin(azimuth), -0.1 + 0.03 * (k % 8));
          const double a = rayDistance(scene, p, dir, 40.0);
          const double b = rayDistance(scene, p + shift, dir, 40.0);
          if (std::isinf(a) || std::isinf(b))
          {
            EXPECT_EQ(std::isinf(a), std::isinf(b)) << seed << " " << t << " " << k;
          }
          else
          {
            EXPECT_NEAR(a, b, 1e-6) << seed << " " << t << " " << k;
          }
        }
      }
    }
  }
}

TEST(SimLoops, RepetitiveRevisitsExactlyWhenDrawn)
{
  int with = 0;
  int without = 0;
  for (unsigned seed = 0; seed < 16; ++seed)
  {
    const FamilyDraw draw = aloam::sim::drawFamily(Family::LoopRepetitive, seed, kLoopDuration);
    const aloam::sim::PoseFunction motion = aloam::sim::familyMotion(draw);
    const std::vector<aloam::sim::Revisit> revisits = aloam::sim::trueRevisits(motion, kLoopDuration, kSweep);
    const bool drawn = *draw.parameter("revisit") > 0.5;
    EXPECT_EQ(!revisits.empty(), drawn) << seed << " " << draw.describe();
    (drawn ? with : without)++;
    // Places one period apart look the same: the drive passes several of them either way.
    int look_alikes = 0;
    const double period = draw.block_period_m;
    for (double t = 0.0; t < kLoopDuration; t += 1.0)
    {
      const Eigen::Vector3d p = motion(t).translation();
      for (double s = 0.0; s < t - 30.0; s += 0.1)
      {
        const Eigen::Vector3d q = motion(s).translation();
        const Eigen::Vector3d d = p - q;
        const double rx = d.x() - period * std::round(d.x() / period);
        const double ry = d.y() - period * std::round(d.y() / period);
        if (std::hypot(rx, ry) < 1.0 && d.head<2>().norm() > period - 1.0)
        {
          ++look_alikes;
          break;
        }
      }
    }
    EXPECT_GT(look_alikes, 3) << seed;
  }
  EXPECT_GT(with, 0);
  EXPECT_GT(without, 0);
}

TEST(SimLoops, TrueRevisitsOfASampledTrajectory)
{
  // A circle of 20 m radius at 2 m/s: a lap every 62.8 s.
  std::vector<double> times;
  std::vector<Eigen::Isometry3d> poses;
  for (double t = 0.0; t <= 100.0; t += 0.5)
  {
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.translation() = Eigen::Vector3d(20.0 * std::cos(0.1 * t), 20.0 * std::sin(0.1 * t), 1.8);
    times.push_back(t);
    poses.push_back(pose);
  }
  const std::vector<aloam::sim::Revisit> revisits = aloam::sim::trueRevisits(times, poses, 2.0, 30.0);
  ASSERT_FALSE(revisits.empty());
  for (const aloam::sim::Revisit& r : revisits)
  {
    EXPECT_NEAR(r.later_s - r.earlier_s, 2.0 * kPi / 0.1, 1.0);
    EXPECT_LE(r.distance_m, 2.0);
  }
  EXPECT_NEAR(revisits.front().later_s, 2.0 * kPi / 0.1 - 1.0, 0.6);
  EXPECT_THROW(aloam::sim::trueRevisits(times, std::vector<Eigen::Isometry3d>(3), 2.0, 30.0), std::invalid_argument);
}

TEST(SimLoops, RoundedPathCornersAreSmooth)
{
  const std::vector<Eigen::Vector2d> square = { Eigen::Vector2d(50, 0), Eigen::Vector2d(100, 0),
                                                Eigen::Vector2d(100, 100), Eigen::Vector2d(0, 100),
                                                Eigen::Vector2d(0, 0) };
  const aloam::sim::RoundedPath path(square, true, 20.0);
  EXPECT_TRUE(path.position(0.0).isApprox(Eigen::Vector2d(50, 0), 1e-9));
  EXPECT_NEAR(path.heading(path.length()), 2.0 * kPi, 1e-9);
  EXPECT_LT(path.length(), 400.0);
  EXPECT_GT(path.length(), 380.0);
  double previous = path.position(0.0).x();
  for (double s = 0.05; s <= 2.0 * path.length(); s += 0.05)
  {
    // Unit speed along s, heading equal to the tangent, curvature the heading's derivative.
    const Eigen::Vector2d d = path.position(s) - path.position(s - 0.05);
    EXPECT_NEAR(d.norm(), 0.05, 1e-4) << s;
    const double mid = path.heading(s - 0.025);
    EXPECT_NEAR(wrapAngle(std::atan2(d.y(), d.x()) - mid), 0.0, 5e-4) << s;
    EXPECT_NEAR((path.heading(s) - path.heading(s - 0.05)) / 0.05, path.curvature(s - 0.025), 1e-3) << s;
    previous = d.x();
  }
  (void)previous;
  // The whole path stays within the square's rounded corners: never outside it.
  for (double s = 0.0; s < path.length(); s += 0.5)
  {
    const Eigen::Vector2d p = path.position(s);
    EXPECT_GE(p.x(), -1e-6);
    EXPECT_LE(p.x(), 100.0 + 1e-6);
    EXPECT_GE(p.y(), -1e-6);
    EXPECT_LE(p.y(), 100.0 + 1e-6);
  }
  EXPECT_THROW(
      aloam::sim::RoundedPath({ Eigen::Vector2d(0, 0), Eigen::Vector2d(10, 0), Eigen::Vector2d(0, 0) }, false, 5.0),
      std::invalid_argument);
  EXPECT_THROW(
      aloam::sim::RoundedPath({ Eigen::Vector2d(0, 0), Eigen::Vector2d(10, 0), Eigen::Vector2d(10, 5) }, false, 20.0),
      std::invalid_argument);
}

}  // namespace
