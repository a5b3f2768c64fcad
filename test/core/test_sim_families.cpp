// Scene families of the simulator (issue 23): a draw is a function of (family, seed) only, every drawn
// parameter stays in its family's range, the scenes build and the motion stays inside them, and the corridor
// of issue 23 has the geometry the issue describes.
#include <algorithm>
#include <cmath>
#include <limits>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "aloam_nodelet/core/sensor_model.h"
#include "aloam_nodelet/sim/families.h"

namespace
{
using aloam::sim::Family;
using aloam::sim::FamilyDraw;

constexpr double kPi = 3.14159265358979323846;
constexpr double kDuration = 15.0;  // s, as eval_families.sh simulates
constexpr unsigned kRangeSeeds = 200;

std::vector<Family> randomFamilies()
{
  std::vector<Family> families;
  for (const std::string& name : aloam::sim::familyNames())
  {
    const Family family = *aloam::sim::familyFromName(name);
    if (family != Family::CorridorIssue23)
    {
      families.push_back(family);
    }
  }
  return families;
}

double distanceAlong(const aloam::sim::Scene& scene, const Eigen::Vector3d& origin, const Eigen::Vector3d& direction)
{
  const auto hit = scene.intersect(origin, direction, 400.0);
  return hit ? hit->distance : std::numeric_limits<double>::infinity();
}

TEST(SimFamilies, NamesRoundTrip)
{
  ASSERT_EQ(aloam::sim::familyNames().size(), 11u);
  for (const std::string& name : aloam::sim::familyNames())
  {
    const auto family = aloam::sim::familyFromName(name);
    ASSERT_TRUE(family.has_value()) << name;
    EXPECT_EQ(aloam::sim::familyName(*family), name);
  }
  EXPECT_FALSE(aloam::sim::familyFromName("cave").has_value());
  EXPECT_THROW(aloam::sim::drawFamily(Family::Corridor, 1, 0.0), std::invalid_argument);
}

TEST(SimFamilies, SameSeedSameDrawSceneAndMotion)
{
  for (const std::string& name : aloam::sim::familyNames())
  {
    const Family family = *aloam::sim::familyFromName(name);
    for (unsigned seed = 0; seed < 5; ++seed)
    {
      const FamilyDraw a = aloam::sim::drawFamily(family, seed, kDuration);
      const FamilyDraw b = aloam::sim::drawFamily(family, seed, kDuration);
      EXPECT_EQ(a.describe(), b.describe());
      const aloam::sim::Scene scene_a = aloam::sim::familyScene(a);
      const aloam::sim::Scene scene_b = aloam::sim::familyScene(b);
      EXPECT_EQ(scene_a.size(), scene_b.size()) << name;
      for (const double t : { 0.0, 3.3, kDuration })
      {
        EXPECT_TRUE(aloam::sim::familyMotion(a)(t).isApprox(aloam::sim::familyMotion(b)(t), 0.0)) << name << " " << t;
      }
    }
  }
}

TEST(SimFamilies, DescribeIsOneKeyValueLine)
{
  const FamilyDraw draw = aloam::sim::drawFamily(Family::Corridor, 7, kDuration);
  const std::string line = draw.describe();
  EXPECT_EQ(line.find('\n'), std::string::npos);
  EXPECT_EQ(line.rfind("family=corridor seed=7 motion=", 0), 0u) << line;
  EXPECT_NE(line.find(" width_m="), std::string::npos) << line;
}

TEST(SimFamilies, DifferentSeedsDrawDifferentScenes)
{
  for (const Family family : randomFamilies())
  {
    std::set<std::string> lines;
    for (unsigned seed = 0; seed < 20; ++seed)
    {
      std::string line = aloam::sim::drawFamily(family, seed, kDuration).describe();
      lines.insert(line.substr(line.find(" motion=")));  // without the seed itself
    }
    EXPECT_EQ(lines.size(), 20u) << aloam::sim::familyName(family);
  }
}

TEST(SimFamilies, EveryParameterStaysInItsRangeAndTheMotionInTheScene)
{
  for (const Family family : randomFamilies())
  {
    const std::string name = aloam::sim::familyName(family);
    int hand_held = 0;
    int other = 0;
    for (unsigned seed = 0; seed < kRangeSeeds; ++seed)
    {
      const FamilyDraw draw = aloam::sim::drawFamily(family, seed, kDuration);
      ASSERT_FALSE(draw.parameters.empty());
      for (const aloam::sim::DrawnParameter& p : draw.parameters)
      {
        EXPECT_GE(p.value, p.lo) << name << " seed " << seed << " " << p.key;
        EXPECT_LE(p.value, p.hi) << name << " seed " << seed << " " << p.key;
      }
      // The issue's ranges, checked on the options the scene is built from.
      if (draw.motion == aloam::sim::MotionKind::HandHeld)
      {
        ++hand_held;
        EXPECT_LE(draw.walk.roll_amplitude_rad, 15.0 * kPi / 180.0 + 1e-12);
        EXPECT_LE(draw.walk.burst_rate_rad_s, 120.0 * kPi / 180.0 + 1e-12);
        EXPECT_GE(draw.walk.burst_rate_rad_s, 0.0);
      }
      else
      {
        ++other;
      }
      if (family == Family::Corridor && !draw.corridor_turn)
      {
        EXPECT_GE(draw.corridor.width_m, 1.8);
        EXPECT_LE(draw.corridor.width_m, 4.0);
        EXPECT_GE(draw.corridor.length_m, 50.0);
        EXPECT_LE(draw.corridor.length_m, 300.0);
        // The walk stays between the end walls, at least 1.5 m from them.
        const double start = draw.walk.start_x;
        const double end = draw.walk.start_x + aloam::sim::handHeldDistance(draw.walk, kDuration);
        EXPECT_GE(start, 1.5 - 1e-9) << seed;
        EXPECT_LE(end, draw.corridor.length_m - 1.5 + 1e-9) << seed;
      }
      if (family == Family::Corridor && draw.corridor_turn)
      {
        EXPECT_GE(draw.office.width_m, 1.8);
        EXPECT_LE(draw.office.width_m, 4.0);
      }
      // Builds (throws on invalid dimensions) and the sensor is in free space at the start and the end.
      const aloam::sim::Scene scene = aloam::sim::familyScene(draw);
      const aloam::sim::PoseFunction motion = aloam::sim::familyMotion(draw);
      for (const double t : { 0.0, kDuration })
      {
        const Eigen::Vector3d position = motion(t).translation();
        const double down = distanceAlong(scene, position, -Eigen::Vector3d::UnitZ());
        EXPECT_GT(down, 0.5) << name << " seed " << seed << " t " << t;
        EXPECT_LT(down, 3.0) << name << " seed " << seed << " t " << t;
        if (family == Family::Corridor || family == Family::Office || family == Family::Stairwell)
        {
          // Indoors: under a ceiling (a stairwell's is above its top floor), a wall within 2.5 m (half the
          // widest corridor plus a recess).
          EXPECT_LT(distanceAlong(scene, position, Eigen::Vector3d::UnitZ()), 8.0) << name << " seed " << seed;
          double nearest = std::numeric_limits<double>::infinity();
          for (int k = 0; k < 16; ++k)
          {
            const double azimuth = 2.0 * kPi * k / 16;
            nearest = std::min(
                nearest, distanceAlong(scene, position, Eigen::Vector3d(std::cos(azimuth), std::sin(azimuth), 0.0)));
          }
          EXPECT_LT(nearest, 2.5) << name << " seed " << seed << " t " << t;
        }
      }
    }
    if (family == Family::Urban || family == Family::Field)
    {
      EXPECT_GT(hand_held, 40) << name;
      EXPECT_GT(other, 40) << name;
    }
  }
}

TEST(SimFamilies, HandHeldDrawsCoverStartsAtRestStopsAndStrongBursts)
{
  int at_rest = 0;
  int stops = 0;
  int strong = 0;
  for (unsigned seed = 0; seed < kRangeSeeds; ++seed)
  {
    const FamilyDraw draw = aloam::sim::drawFamily(Family::Corridor, seed, kDuration);
    if (draw.motion != aloam::sim::MotionKind::HandHeld)
    {
      continue;
    }
    if (draw.walk.start_rest_s > 0.0)
    {
      ++at_rest;
      EXPECT_EQ(aloam::sim::handHeldSpeed(draw.walk, 0.0), 0.0);
      EXPECT_TRUE(aloam::sim::familyMotion(draw)(0.0).translation().isApprox(
          aloam::sim::familyMotion(draw)(0.9 * draw.walk.start_rest_s).translation(), 1e-12));
    }
    stops += draw.walk.stop_interval_s > 0.0 ? 1 : 0;
    strong += draw.walk.burst_rate_rad_s > 90.0 * kPi / 180.0 ? 1 : 0;
  }
  EXPECT_GT(at_rest, 10);
  EXPECT_GT(stops, 10);
  EXPECT_GT(strong, 10);
}

TEST(SimFamilies, BurstsAtGivenTimesIntegrateToTheYaw)
{
  aloam::sim::HandHeldOptions walk;
  walk.burst_times_s = { 0.7, 2.9, 4.1, 8.0 };
  walk.burst_rate_rad_s = 1.2;
  walk.start_rest_s = 1.0;
  constexpr double kDt = 1e-3;
  double integral = 0.0;
  double walked = 0.0;
  for (double t = 0.0; t < 10.0; t += kDt)
  {
    integral += kDt * aloam::sim::handHeldYawRate(walk, t + 0.5 * kDt);
    walked += kDt * aloam::sim::handHeldSpeed(walk, t + 0.5 * kDt);
    EXPECT_NEAR(integral, aloam::sim::handHeldYaw(walk, t + kDt), 1e-5) << t;
    EXPECT_NEAR(walked, aloam::sim::handHeldDistance(walk, t + kDt), 1e-5) << t;
  }
  EXPECT_EQ(aloam::sim::handHeldYawRate(walk, 0.5), 0.0);
  EXPECT_NEAR(aloam::sim::handHeldYawRate(walk, 0.7 + 0.25), 1.2, 1e-12);   // first burst: left
  EXPECT_NEAR(aloam::sim::handHeldYawRate(walk, 2.9 + 0.25), -1.2, 1e-12);  // second: right
  EXPECT_EQ(aloam::sim::handHeldSpeed(walk, 0.5), 0.0);
  EXPECT_NEAR(aloam::sim::handHeldSpeed(walk, 2.0), walk.speed, 1e-12);
}

TEST(SimFamilies, Issue23CorridorHasTheAskedGeometry)
{
  const FamilyDraw draw = aloam::sim::drawFamily(Family::CorridorIssue23, 3, kDuration);
  EXPECT_DOUBLE_EQ(*draw.parameter("width_m"), 2.5);
  EXPECT_DOUBLE_EQ(*draw.parameter("length_m"), 200.0);
  EXPECT_DOUBLE_EQ(*draw.parameter("sway_deg"), 10.0);
  EXPECT_DOUBLE_EQ(*draw.parameter("burst_deg_s"), 90.0);
  EXPECT_DOUBLE_EQ(draw.walk.speed, 1.4);
  EXPECT_GT(aloam::sim::handHeldSpeed(draw.walk, 0.0), 1.39);  // moving from the first sweep
  const aloam::sim::Scene scene = aloam::sim::familyScene(draw);
  const aloam::sim::PoseFunction motion = aloam::sim::familyMotion(draw);

  // From the start: the back wall 15 m behind, the walls 1.25 m to the sides, the front wall 185 m ahead.
  const Eigen::Vector3d start = motion(0.0).translation();
  EXPECT_NEAR(start.x(), 15.0, 1e-9);
  EXPECT_NEAR(distanceAlong(scene, start, -Eigen::Vector3d::UnitX()), 15.0, 1e-6);
  EXPECT_NEAR(distanceAlong(scene, start, Eigen::Vector3d::UnitX()), 185.0, 1e-6);
  EXPECT_NEAR(distanceAlong(scene, start, Eigen::Vector3d::UnitY()), 1.25, 1e-6);
  EXPECT_NEAR(distanceAlong(scene, start, -Eigen::Vector3d::UnitY()), 1.25, 1e-6);
  // Over the walk the back wall is 15-36 m behind.
  const double end_x = motion(kDuration).translation().x();
  EXPECT_GT(end_x, 15.0 + 19.0);
  EXPECT_LE(end_x, 36.0 + 1e-9);

  // Along both walls at door height: exactly six recesses 0.25 m deep, the first 40 m ahead of the start.
  std::vector<double> recess_starts;
  bool in_recess = false;
  for (double x = 0.5; x < 199.5; x += 0.05)
  {
    bool recess = false;
    for (const double side : { 1.0, -1.0 })
    {
      const double d = distanceAlong(scene, Eigen::Vector3d(x, 0.0, 1.0), Eigen::Vector3d(0.0, side, 0.0));
      EXPECT_TRUE(std::abs(d - 1.25) < 1e-6 || std::abs(d - 1.5) < 1e-6) << x << " " << d;
      recess = recess || d > 1.3;
    }
    if (recess && !in_recess)
    {
      recess_starts.push_back(x);
    }
    in_recess = recess;
  }
  ASSERT_EQ(recess_starts.size(), 6u);
  EXPECT_NEAR(recess_starts.front() + 0.5 - start.x(), 40.0, 0.1);  // door centers; doors are 1 m wide

  // A VLP-16 sweep from the start: nothing beyond the end walls or the side walls (no lights, no niches),
  // the back wall seen 15 m behind.
  const aloam::SensorModel vlp16 = *aloam::SensorModel::fromPreset("VLP16");
  aloam::sim::ScanOptions options;
  options.max_range = 300.0;
  const aloam::Cloud cloud = aloam::sim::scanStatic(scene, vlp16, motion(0.0), options);
  ASSERT_GT(cloud.size(), 1000u);
  double farthest_behind = 0.0;
  for (const aloam::Point& p : cloud.points)
  {
    const Eigen::Vector3d world = motion(0.0) * Eigen::Vector3d(p.x, p.y, p.z);
    EXPECT_GE(world.x(), -1e-3);
    EXPECT_LE(world.x(), 200.0 + 1e-3);
    EXPECT_LE(std::abs(world.y()), 1.5 + 1e-3);
    farthest_behind = std::max(farthest_behind, start.x() - world.x());
  }
  EXPECT_NEAR(farthest_behind, 15.0, 0.01);
}

}  // namespace
