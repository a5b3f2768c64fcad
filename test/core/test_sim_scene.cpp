// Tests of the synthetic scene and the lidar ray-caster (aloam::sim).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "aloam_nodelet/core/sensor_model.h"
#include "aloam_nodelet/sim/raycaster.h"
#include "aloam_nodelet/sim/scene.h"
#include "aloam_nodelet/sim/scenes_extra.h"

namespace aloam
{
namespace sim
{
namespace
{
constexpr double kEps = 1e-9;
constexpr double kRadToDeg = 180.0 / M_PI;
constexpr double kSensorHeight = 1.8;

SensorModel preset(const std::string& name)
{
  const std::optional<SensorModel> model = SensorModel::fromPreset(name);
  EXPECT_TRUE(model.has_value());
  return *model;
}

Eigen::Isometry3d poseXYZYaw(double x, double y, double z, double yaw)
{
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translation() = Eigen::Vector3d(x, y, z);
  pose.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return pose;
}

// A sensor that drives, climbs and turns about all three axes during the sweep.
Eigen::Isometry3d wobblingPose(double t)
{
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translation() = Eigen::Vector3d(40.0 + 10.0 * t, 0.5 - 3.0 * t, kSensorHeight + 4.0 * t);
  pose.linear() =
      (Eigen::AngleAxisd(0.2 + 5.0 * t, Eigen::Vector3d::UnitZ()) *
       Eigen::AngleAxisd(-2.0 * t, Eigen::Vector3d::UnitY()) * Eigen::AngleAxisd(1.5 * t, Eigen::Vector3d::UnitX()))
          .toRotationMatrix();
  return pose;
}

Eigen::Vector3d toVector(const Point& p)
{
  return Eigen::Vector3d(p.x, p.y, p.z);
}

bool samePoints(const Cloud& a, const Cloud& b)
{
  if (a.size() != b.size())
  {
    return false;
  }
  for (std::size_t i = 0; i < a.size(); ++i)
  {
    const Point& p = a[i];
    const Point& q = b[i];
    if (p.x != q.x || p.y != q.y || p.z != q.z || p.intensity != q.intensity || p.time != q.time || p.ring != q.ring)
    {
      return false;
    }
  }
  return true;
}
}  // namespace

// ---------------------------------------------------------------------------------------------
// Primitives and single rays

TEST(SimScene, RayStraightDownHitsFlatGroundAtHeight)
{
  const Scene scene = Scene::flatGround();
  for (const double h : { 0.3, 1.7, 12.5 })
  {
    const auto hit = scene.intersect(Eigen::Vector3d(3.0, -2.0, h), Eigen::Vector3d(0.0, 0.0, -1.0), 100.0);
    ASSERT_TRUE(hit.has_value());
    EXPECT_NEAR(hit->distance, h, kEps);
    EXPECT_NEAR(hit->point.z(), 0.0, kEps);
    EXPECT_NEAR(hit->normal.z(), 1.0, kEps);
    EXPECT_EQ(hit->surface_class, SurfaceClass::Ground);
    EXPECT_EQ(hit->surface_id, 0);
  }
  // Direction length does not matter.
  const auto hit = scene.intersect(Eigen::Vector3d(0.0, 0.0, 2.0), Eigen::Vector3d(0.0, 0.0, -7.0), 100.0);
  ASSERT_TRUE(hit.has_value());
  EXPECT_NEAR(hit->distance, 2.0, kEps);
}

TEST(SimScene, RayHitsBoxFaceAtExpectedDistance)
{
  const Scene scene = Scene::simpleBox();
  // Box faces at x = 8 and 12, y = +-3, top at z = 3.
  auto hit = scene.intersect(Eigen::Vector3d(0.0, 0.0, 1.0), Eigen::Vector3d::UnitX(), 100.0);
  ASSERT_TRUE(hit.has_value());
  EXPECT_NEAR(hit->distance, 8.0, kEps);
  EXPECT_NEAR(hit->normal.x(), -1.0, kEps);
  EXPECT_EQ(hit->surface_class, SurfaceClass::Building);

  hit = scene.intersect(Eigen::Vector3d(10.0, -10.0, 2.0), Eigen::Vector3d::UnitY(), 100.0);
  ASSERT_TRUE(hit.has_value());
  EXPECT_NEAR(hit->distance, 7.0, kEps);
  EXPECT_NEAR(hit->normal.y(), -1.0, kEps);

  hit = scene.intersect(Eigen::Vector3d(10.0, 1.0, 5.0), -Eigen::Vector3d::UnitZ(), 100.0);
  ASSERT_TRUE(hit.has_value());
  EXPECT_NEAR(hit->distance, 2.0, kEps);
  EXPECT_NEAR(hit->normal.z(), 1.0, kEps);

  // max_range is inclusive and cuts off farther hits.
  EXPECT_FALSE(scene.intersect(Eigen::Vector3d(0.0, 0.0, 1.0), Eigen::Vector3d::UnitX(), 7.9).has_value());
  EXPECT_TRUE(scene.intersect(Eigen::Vector3d(0.0, 0.0, 1.0), Eigen::Vector3d::UnitX(), 8.0).has_value());
}

TEST(SimScene, RotatedBoxCornerFacesTheRay)
{
  Scene scene;
  scene.add(OrientedBox(Eigen::Vector3d(10.0, 0.0, 1.0), Eigen::Vector3d(1.0, 1.0, 1.0), M_PI / 4.0),
            SurfaceClass::Other);
  const auto hit = scene.intersect(Eigen::Vector3d(0.0, 0.0, 1.0), Eigen::Vector3d::UnitX(), 100.0);
  ASSERT_TRUE(hit.has_value());
  EXPECT_NEAR(hit->distance, 10.0 - std::sqrt(2.0), 1e-9);
  // Slightly off the corner the ray hits a face whose normal is at 45 degrees.
  const auto side = scene.intersect(Eigen::Vector3d(0.0, 0.2, 1.0), Eigen::Vector3d::UnitX(), 100.0);
  ASSERT_TRUE(side.has_value());
  EXPECT_NEAR(side->distance, 10.0 - std::sqrt(2.0) + 0.2, 1e-9);
  EXPECT_NEAR(std::abs(side->normal.x()), std::sqrt(0.5), 1e-9);
}

TEST(SimScene, RayMissingEverythingReturnsNullopt)
{
  const Scene scene = Scene::simpleBox();
  EXPECT_FALSE(scene.intersect(Eigen::Vector3d(0.0, 0.0, 1.0), Eigen::Vector3d::UnitZ(), 100.0).has_value());
  EXPECT_FALSE(scene.intersect(Eigen::Vector3d(0.0, 0.0, 1.0), Eigen::Vector3d(-1.0, 0.0, 0.05), 1000.0).has_value());
  // Just above the box.
  EXPECT_FALSE(scene.intersect(Eigen::Vector3d(0.0, 0.0, 3.01), Eigen::Vector3d::UnitX(), 1000.0).has_value());
  EXPECT_FALSE(scene.intersect(Eigen::Vector3d(0.0, 0.0, 1.0), Eigen::Vector3d::Zero(), 100.0).has_value());
  EXPECT_FALSE(Scene().intersect(Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitX(), 100.0).has_value());
}

TEST(SimScene, CylinderSphereAndSlopedPlane)
{
  Scene scene;
  const int pole = scene.add(VerticalCylinder(5.0, 0.0, 0.2, 0.0, 6.0), SurfaceClass::Pole);
  const int crown = scene.add(Sphere(Eigen::Vector3d(0.0, 10.0, 5.0), 2.0), SurfaceClass::TreeCrown);
  const int ramp = scene.add(PlanePatch(0.1, 0.0, 0.0, 2.0, 8.0, -20.0, -10.0), SurfaceClass::Ground);

  auto hit = scene.intersect(Eigen::Vector3d(0.0, 0.0, 1.0), Eigen::Vector3d::UnitX(), 100.0);
  ASSERT_TRUE(hit.has_value());
  EXPECT_EQ(hit->surface_id, pole);
  EXPECT_NEAR(hit->distance, 4.8, kEps);
  EXPECT_NEAR(hit->normal.x(), -1.0, kEps);
  // Over the top of the pole: miss; straight down onto its cap.
  EXPECT_FALSE(scene.intersect(Eigen::Vector3d(0.0, 0.0, 6.5), Eigen::Vector3d::UnitX(), 100.0).has_value());
  hit = scene.intersect(Eigen::Vector3d(5.1, 0.0, 10.0), -Eigen::Vector3d::UnitZ(), 100.0);
  ASSERT_TRUE(hit.has_value());
  EXPECT_NEAR(hit->distance, 4.0, kEps);

  hit = scene.intersect(Eigen::Vector3d(0.0, 0.0, 5.0), Eigen::Vector3d::UnitY(), 100.0);
  ASSERT_TRUE(hit.has_value());
  EXPECT_EQ(hit->surface_id, crown);
  EXPECT_NEAR(hit->distance, 8.0, kEps);

  // z = 0.1 x: from (5, -15, 3) straight down the ramp is at z = 0.5.
  hit = scene.intersect(Eigen::Vector3d(5.0, -15.0, 3.0), -Eigen::Vector3d::UnitZ(), 100.0);
  ASSERT_TRUE(hit.has_value());
  EXPECT_EQ(hit->surface_id, ramp);
  EXPECT_NEAR(hit->distance, 2.5, kEps);
  EXPECT_NEAR(hit->normal.dot(Eigen::Vector3d(-0.1, 0.0, 1.0).normalized()), 1.0, kEps);
  // Outside the ramp's rectangle: miss.
  EXPECT_FALSE(scene.intersect(Eigen::Vector3d(9.0, -15.0, 3.0), -Eigen::Vector3d::UnitZ(), 100.0).has_value());
}

TEST(SimScene, InvalidShapesThrow)
{
  EXPECT_THROW(VerticalCylinder(0.0, 0.0, 0.0, 0.0, 1.0), std::invalid_argument);
  EXPECT_THROW(VerticalCylinder(0.0, 0.0, 1.0, 1.0, 1.0), std::invalid_argument);
  EXPECT_THROW(Sphere(Eigen::Vector3d::Zero(), -1.0), std::invalid_argument);
  EXPECT_THROW(OrientedBox(Eigen::Vector3d::Zero(), Eigen::Vector3d(1.0, 0.0, 1.0)), std::invalid_argument);
  EXPECT_THROW(PlanePatch::horizontal(0.0, 1.0, -1.0, 0.0, 1.0), std::invalid_argument);
}

// ---------------------------------------------------------------------------------------------
// Acceleration and the street builder

TEST(SimScene, GridAgreesWithBruteForce)
{
  const Scene scene = Scene::urbanStreet(7);
  // The same primitives added one by one (the grid grows incrementally) must answer the same.
  Scene incremental;
  for (const Primitive& p : scene.primitives())
  {
    incremental.add(p);
  }
  std::mt19937 gen(123);
  std::uniform_real_distribution<double> along(-80.0, 380.0);
  std::uniform_real_distribution<double> across(-3.0, 3.0);
  std::uniform_real_distribution<double> height(0.5, 30.0);
  std::normal_distribution<double> normal(0.0, 1.0);
  int hits = 0;
  const int num_rays = 20000;
  for (int i = 0; i < num_rays; ++i)
  {
    const Eigen::Vector3d origin(along(gen), across(gen), height(gen));
    Eigen::Vector3d dir(normal(gen), normal(gen), normal(gen));
    if (i % 4 == 0)
    {
      dir.z() = 0.0;  // horizontal rays, incl. axis-parallel ones below
    }
    if (i % 16 == 0)
    {
      dir = Eigen::Vector3d(i % 32 == 0 ? 1.0 : 0.0, i % 32 == 0 ? 0.0 : -1.0, 0.0);
    }
    const double range = 150.0;
    const auto fast = scene.intersect(origin, dir, range);
    const auto slow = scene.intersectBruteForce(origin, dir, range);
    const auto grown = incremental.intersect(origin, dir, range);
    ASSERT_EQ(fast.has_value(), slow.has_value()) << "ray " << i;
    ASSERT_EQ(fast.has_value(), grown.has_value()) << "ray " << i;
    if (fast)
    {
      ++hits;
      EXPECT_NEAR(fast->distance, slow->distance, 1e-9) << "ray " << i;
      EXPECT_NEAR(grown->distance, slow->distance, 1e-9) << "ray " << i;
    }
  }
  EXPECT_GT(hits, num_rays / 2);
}

TEST(SimScene, UrbanStreetContentsAndClearCenterline)
{
  const double length = 300.0;
  const Scene scene = Scene::urbanStreet(3, length);
  const UrbanStreetOptions defaults;
  const double street_span = length + 2.0 * defaults.end_margin_m;
  // Poles on both sides at most pole_spacing_max_m apart.
  EXPECT_GE(scene.countClass(SurfaceClass::Pole),
            static_cast<int>(2.0 * street_span / defaults.pole_spacing_max_m) - 2);
  EXPECT_GT(scene.countClass(SurfaceClass::Building), 10);
  EXPECT_GT(scene.countClass(SurfaceClass::Vehicle), 10);
  EXPECT_GT(scene.countClass(SurfaceClass::TreeTrunk), 0);
  EXPECT_EQ(scene.countClass(SurfaceClass::TreeTrunk), scene.countClass(SurfaceClass::TreeCrown));

  // Nothing but ground intrudes into the corridor a car on the centerline sweeps.
  Aabb corridor;
  corridor.min = Eigen::Vector3d(0.0, -1.5, 0.2);
  corridor.max = Eigen::Vector3d(length, 1.5, 2.5);
  for (const Primitive& p : scene.primitives())
  {
    if (p.surface_class == SurfaceClass::Ground)
    {
      continue;
    }
    const Aabb b = shapeBounds(p.shape);
    const bool overlaps =
        (b.min.array() <= corridor.max.array()).all() && (b.max.array() >= corridor.min.array()).all();
    EXPECT_FALSE(overlaps);
  }
  // Looking sideways from the street mostly sees facades, cars, poles or trees just beyond the
  // curb; a few rays escape through alleys between buildings.
  const double max_near =
      0.5 * defaults.street_width_max_m + defaults.sidewalk_width_m + defaults.building_setback_max_m;
  int near_hits = 0;
  int escapes = 0;
  int rays = 0;
  for (double x = 0.0; x <= length; x += 0.5, ++rays)
  {
    for (const double side : { -1.0, 1.0 })
    {
      const auto hit = scene.intersect(Eigen::Vector3d(x, 0.0, kSensorHeight), Eigen::Vector3d(0.0, side, 0.0), 100.0);
      near_hits += hit && hit->distance <= max_near ? 1 : 0;
      escapes += hit ? 0 : 1;
    }
  }
  EXPECT_GT(near_hits, 2 * rays * 6 / 10);
  EXPECT_GT(escapes, 0);
}

TEST(SimScene, SameSeedSameSceneDifferentSeedDifferentScene)
{
  const Scene a = Scene::urbanStreet(11);
  const Scene b = Scene::urbanStreet(11);
  const Scene c = Scene::urbanStreet(12);
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i)
  {
    const Aabb ba = shapeBounds(a.primitives()[i].shape);
    const Aabb bb = shapeBounds(b.primitives()[i].shape);
    EXPECT_EQ(ba.min, bb.min);
    EXPECT_EQ(ba.max, bb.max);
    EXPECT_EQ(a.primitives()[i].reflectivity, b.primitives()[i].reflectivity);
  }
  bool differs = a.size() != c.size();
  for (std::size_t i = 0; !differs && i < a.size(); ++i)
  {
    differs = shapeBounds(a.primitives()[i].shape).max != shapeBounds(c.primitives()[i].shape).max;
  }
  EXPECT_TRUE(differs);

  const SensorModel model = preset("VLP16");
  const Eigen::Isometry3d pose = poseXYZYaw(60.0, 0.0, kSensorHeight, 0.0);
  const Cloud cloud_a = scanStatic(a, model, pose, ScanOptions());
  EXPECT_TRUE(samePoints(cloud_a, scanStatic(b, model, pose, ScanOptions())));
  EXPECT_FALSE(samePoints(cloud_a, scanStatic(c, model, pose, ScanOptions())));
}

// ---------------------------------------------------------------------------------------------
// Ray-caster

TEST(SimRaycaster, StaticScanRingsTimesAndAzimuths)
{
  const Scene scene = Scene::urbanStreet(1);
  const SensorModel model = preset("VLP16");
  ScanOptions options;
  options.start_azimuth_rad = 0.7;
  std::vector<int> ids;
  const Cloud cloud = scanStatic(scene, model, poseXYZYaw(50.0, 0.5, kSensorHeight, 0.3), options, &ids);

  const std::size_t num_rays = static_cast<std::size_t>(model.numRings()) * model.columns();
  EXPECT_GT(cloud.size(), num_rays / 2);
  EXPECT_LE(cloud.size(), num_rays);
  ASSERT_EQ(ids.size(), cloud.size());
  EXPECT_EQ(cloud.width, cloud.size());
  EXPECT_EQ(cloud.height, 1u);

  const double period = model.scanPeriod();
  float previous_time = 0.0F;
  int previous_column = -1;
  int previous_ring = -1;
  for (std::size_t i = 0; i < cloud.size(); ++i)
  {
    const Point& p = cloud[i];
    ASSERT_LT(p.ring, model.numRings());
    const double elevation_deg = std::atan2(p.z, std::hypot(p.x, p.y)) * kRadToDeg;
    EXPECT_NEAR(elevation_deg, model.elevationsDeg()[p.ring], 0.01);
    EXPECT_EQ(model.ringForElevation(elevation_deg / kRadToDeg), p.ring);
    EXPECT_GE(p.time, 0.0F);
    EXPECT_LT(p.time, period);
    EXPECT_GE(p.time, previous_time);
    previous_time = p.time;

    // Column-major order: within a column the rings ascend.
    const int column = static_cast<int>(std::lround(p.time / period * model.columns()));
    if (column == previous_column)
    {
      EXPECT_GT(static_cast<int>(p.ring), previous_ring);
    }
    previous_column = column;
    previous_ring = p.ring;

    // Clockwise spin: azimuth = start - 2 pi * column / columns.
    const double expected_azimuth = options.start_azimuth_rad - 2.0 * M_PI * column / model.columns();
    const double azimuth_error = std::remainder(std::atan2(p.y, p.x) - expected_azimuth, 2.0 * M_PI);
    EXPECT_NEAR(azimuth_error, 0.0, 1e-4);

    const double range = toVector(p).norm();
    EXPECT_GE(range, options.min_range);
    EXPECT_LE(range, options.max_range);
    EXPECT_GE(p.intensity, 0.0F);
    EXPECT_LE(p.intensity, 255.0F);
  }
  // The first column starts at the start azimuth and the sweep covers all directions.
  EXPECT_EQ(cloud.front().time, 0.0F);
  EXPECT_GT(cloud.back().time, 0.99 * period);
}

TEST(SimRaycaster, SameSeedSameCloudDifferentSeedDifferentCloud)
{
  const Scene scene = Scene::urbanStreet(5);
  const SensorModel model = preset("VLP16");
  ScanOptions options;
  options.range_noise_sigma = 0.02;
  options.dropout_probability = 0.1;
  options.seed = 42;
  const Cloud a = scan(scene, model, wobblingPose, options);
  const Cloud b = scan(scene, model, wobblingPose, options);
  EXPECT_TRUE(samePoints(a, b));
  options.seed = 43;
  EXPECT_FALSE(samePoints(a, scan(scene, model, wobblingPose, options)));
}

TEST(SimRaycaster, NoiseAndDropoutStatistics)
{
  const Scene scene = Scene::urbanStreet(2);
  const SensorModel model = preset("VLP16");
  const Eigen::Isometry3d pose = poseXYZYaw(100.0, 0.0, kSensorHeight, 0.0);
  ScanOptions options;
  options.min_range = 1.0;  // keep the noiseless and noisy sets of returns identical
  const Cloud clean = scanStatic(scene, model, pose, options);

  options.dropout_probability = 0.3;
  const Cloud dropped = scanStatic(scene, model, pose, options);
  const double kept = static_cast<double>(dropped.size()) / clean.size();
  EXPECT_NEAR(kept, 0.7, 0.02);

  options.dropout_probability = 0.0;
  options.range_noise_sigma = 0.05;
  options.seed = 9;
  const Cloud noisy = scanStatic(scene, model, pose, options);
  ASSERT_EQ(noisy.size(), clean.size());
  double sum = 0.0;
  double sum_sq = 0.0;
  for (std::size_t i = 0; i < clean.size(); ++i)
  {
    ASSERT_EQ(noisy[i].ring, clean[i].ring);
    ASSERT_EQ(noisy[i].time, clean[i].time);
    const Eigen::Vector3d pc = toVector(clean[i]);
    const Eigen::Vector3d pn = toVector(noisy[i]);
    // Noise is along the ray.
    EXPECT_NEAR(pc.normalized().dot(pn.normalized()), 1.0, 1e-6);
    const double e = pn.norm() - pc.norm();
    sum += e;
    sum_sq += e * e;
  }
  const double n = static_cast<double>(clean.size());
  const double mean = sum / n;
  const double sigma = std::sqrt(sum_sq / n - mean * mean);
  EXPECT_NEAR(mean, 0.0, 0.003);
  EXPECT_NEAR(sigma, 0.05, 0.003);
}

TEST(SimRaycaster, MovingSensorPointsLandOnSurfacesAtTheirOwnTime)
{
  // Over flat ground every point, taken back to the world with the pose at its own time, lies at
  // z = 0; with the pose at the sweep start it does not (the sweep is really distorted).
  const Scene ground = Scene::flatGround();
  const SensorModel model = preset("VLP16");
  ScanOptions options;
  options.max_range = 100.0;
  const Cloud cloud = scan(ground, model, wobblingPose, options);
  ASSERT_GT(cloud.size(), 10000u);
  double max_error_start_pose = 0.0;
  for (const Point& p : cloud)
  {
    const Eigen::Vector3d world = wobblingPose(p.time) * toVector(p);
    const double range = toVector(p).norm();
    EXPECT_NEAR(world.z(), 0.0, 1e-6 * range + 1e-5);
    max_error_start_pose = std::max(max_error_start_pose, std::abs((wobblingPose(0.0) * toVector(p)).z()));
  }
  EXPECT_GT(max_error_start_pose, 0.5);

  // In the street each point re-cast from the pose at its time hits the same surface at its range.
  const Scene street = Scene::urbanStreet(4);
  std::vector<int> ids;
  const Cloud moving = scan(street, model, wobblingPose, options, &ids);
  const Cloud still = scanStatic(street, model, wobblingPose(0.0), options);
  EXPECT_FALSE(samePoints(moving, still));
  ASSERT_EQ(ids.size(), moving.size());
  int checked = 0;
  for (std::size_t i = 0; i < moving.size(); i += 7)
  {
    const Point& p = moving[i];
    const Eigen::Isometry3d pose = wobblingPose(p.time);
    const Eigen::Vector3d world = pose * toVector(p);
    const auto hit = street.intersect(pose.translation(), world - pose.translation(), options.max_range);
    ASSERT_TRUE(hit.has_value());
    EXPECT_NEAR(hit->distance, toVector(p).norm(), 1e-4);
    EXPECT_EQ(hit->surface_id, ids[i]);
    ++checked;
  }
  EXPECT_GT(checked, 1000);
}

TEST(SimRaycaster, PerformanceSmoke)
{
  const Scene scene = Scene::urbanStreet(1);
  const auto pose_at = [](double t) { return poseXYZYaw(20.0 + 10.0 * t, 0.0, kSensorHeight, 0.1 * t); };
  for (const std::string name : { "VLP16", "HDL64" })
  {
    const SensorModel model = preset(name);
    const int sweeps = name == "VLP16" ? 50 : 10;
    std::size_t points = 0;
    const auto start = std::chrono::steady_clock::now();
    for (int i = 0; i < sweeps; ++i)
    {
      const double x = 10.0 * i;
      points += scan(
                    scene, model, [&](double t) { return pose_at(t + x / 10.0); }, ScanOptions())
                    .size();
    }
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::printf("[ perf     ] %s on urbanStreet: %.1f sweeps/s (%.2f ms/sweep, %.0f points/sweep)\n", name.c_str(),
                sweeps / seconds, 1e3 * seconds / sweeps, static_cast<double>(points) / sweeps);
    EXPECT_GT(points, 0u);
  }
}

// ---------------------------------------------------------------------------------------------
// Extra scenes: the L-shaped office corridor, the tunnel, the stairwell

namespace
{
constexpr double kNicheDepthM = 0.6;  // corridor niches (scenes_extra.cpp)

/// Distance to the first surface along `direction` (NaN when nothing is hit within 200 m).
double distanceAlong(const Scene& scene, const Eigen::Vector3d& from, const Eigen::Vector3d& direction)
{
  const std::optional<Hit> hit = scene.intersect(from, direction, 200.0);
  return hit ? hit->distance : std::numeric_limits<double>::quiet_NaN();
}
}  // namespace

TEST(SimExtraScenes, OfficeWallsAtTheCorridorWidthAndAnLTurn)
{
  const OfficeOptions o;
  const double half_width = 0.5 * o.width_m;
  const double eye = 1.5;
  const double inner_x = o.first_length_m - o.width_m;
  std::vector<std::vector<double>> profiles;
  int cabinets_seen = 0;
  for (const unsigned seed : { 1U, 2U, 3U })
  {
    const Scene scene = officeScene(seed, o);
    std::vector<double> profile;
    int plain = 0;
    int samples = 0;
    // First corridor, up to the inner corner: walls at the half width (nearer at a cabinet, farther at a door or a
    // niche), no opening sideways, floor and ceiling, and the corner's far wall ahead.
    for (double x = 1.0; x < inner_x - 0.5; x += 0.25)
    {
      const Eigen::Vector3d p(x, 0.0, eye);
      for (const double side : { -1.0, 1.0 })
      {
        const double d = distanceAlong(scene, p, Eigen::Vector3d(0.0, side, 0.0));
        ASSERT_FALSE(std::isnan(d)) << "seed " << seed << " x " << x;
        EXPECT_GE(d, half_width - o.clutter_depth_max_m - 1e-9) << "seed " << seed << " x " << x;
        EXPECT_LE(d, half_width + kNicheDepthM + 1e-9) << "seed " << seed << " x " << x;
        plain += std::abs(d - half_width) < 1e-6 ? 1 : 0;
        cabinets_seen += d < half_width - 0.2 ? 1 : 0;
        ++samples;
        profile.push_back(d);
      }
      EXPECT_NEAR(distanceAlong(scene, p, -Eigen::Vector3d::UnitZ()), eye, 1e-9);
      const double up = distanceAlong(scene, p, Eigen::Vector3d::UnitZ());
      EXPECT_LE(up, o.height_m - eye + 1e-9);
      EXPECT_GE(up, o.height_m - eye - 0.1 - 1e-9);  // a ceiling light at most
      EXPECT_NEAR(distanceAlong(scene, p, Eigen::Vector3d::UnitX()), o.first_length_m - x, kNicheDepthM + 1e-9);
    }
    EXPECT_GT(plain, samples / 2) << "seed " << seed;
    EXPECT_LT(plain, samples) << "seed " << seed;  // some doors, niches or cabinets
    profiles.push_back(profile);

    // The L: from the corner the second corridor is open all the way to its end wall, and the start wall
    // is straight back.
    const Eigen::Vector3d corner(o.turnCenterX(), 0.0, eye);
    EXPECT_NEAR(distanceAlong(scene, corner, Eigen::Vector3d::UnitY()), o.secondEndY(), 1e-6);
    EXPECT_NEAR(distanceAlong(scene, corner, -Eigen::Vector3d::UnitX()), o.turnCenterX(), 1e-6);
    // Second corridor: walls at the half width on both sides of its centerline.
    for (double y = half_width + 0.5; y < o.secondEndY() - 0.5; y += 0.25)
    {
      const Eigen::Vector3d p(o.turnCenterX(), y, eye);
      for (const double side : { -1.0, 1.0 })
      {
        const double d = distanceAlong(scene, p, Eigen::Vector3d(side, 0.0, 0.0));
        ASSERT_FALSE(std::isnan(d)) << "seed " << seed << " y " << y;
        EXPECT_GE(d, half_width - o.clutter_depth_max_m - 1e-9) << "seed " << seed << " y " << y;
        EXPECT_LE(d, half_width + kNicheDepthM + 1e-9) << "seed " << seed << " y " << y;
      }
      EXPECT_NEAR(distanceAlong(scene, p, -Eigen::Vector3d::UnitZ()), eye, 1e-9);
    }
  }
  EXPECT_GT(cabinets_seen, 0);
  EXPECT_NE(profiles[0], profiles[1]);
  EXPECT_NE(profiles[1], profiles[2]);
  EXPECT_THROW(officeScene(1,
                           []
                           {
                             OfficeOptions bad;
                             bad.width_m = 0.8;
                             return bad;
                           }()),
               std::invalid_argument);
}

TEST(SimExtraScenes, TunnelSectionAndSparseFeatures)
{
  TunnelOptions o;
  o.length_m = 200.0;
  const double half_width = 0.5 * o.width_m;
  const double eye = 1.8;
  const double light_z = o.wall_height_m - 0.4;
  for (const unsigned seed : { 1U, 2U })
  {
    const Scene scene = tunnelScene(seed, o);
    int plain = 0;
    int samples = 0;
    int features = 0;
    double last_feature_x = -1e9;
    for (double x = 0.0; x < o.length_m; x += 0.1)
    {
      bool feature_here = false;
      for (const double z : { eye, light_z })
      {
        const Eigen::Vector3d p(x, 0.0, z);
        for (const double side : { -1.0, 1.0 })
        {
          const double d = distanceAlong(scene, p, Eigen::Vector3d(0.0, side, 0.0));
          ASSERT_FALSE(std::isnan(d)) << "seed " << seed << " x " << x;
          EXPECT_GE(d, half_width - 0.25) << "seed " << seed << " x " << x;  // a light or a standpipe
          EXPECT_LE(d, half_width + o.niche_depth_m + 1e-9) << "seed " << seed << " x " << x;
          const bool is_plain = std::abs(d - half_width) < 1e-6;
          plain += is_plain ? 1 : 0;
          feature_here = feature_here || !is_plain;
          ++samples;
        }
      }
      if (feature_here && x - last_feature_x > 2.5)
      {
        ++features;
      }
      if (feature_here)
      {
        last_feature_x = x;
      }
      // Floor below, crown above, and the arch (a polygon inscribed in the circle of radius half_width centered
      // on the wall tops) at 45 degrees.
      const Eigen::Vector3d p(x, 0.0, eye);
      EXPECT_NEAR(distanceAlong(scene, p, -Eigen::Vector3d::UnitZ()), eye, 1e-9);
      EXPECT_NEAR(distanceAlong(scene, p, Eigen::Vector3d::UnitZ()), o.crownHeight() - eye, 1e-6);
      for (const double side : { -1.0, 1.0 })
      {
        const double d = distanceAlong(scene, Eigen::Vector3d(x, 0.0, o.wall_height_m),
                                       Eigen::Vector3d(0.0, side * M_SQRT1_2, M_SQRT1_2));
        EXPECT_LE(d, half_width + 1e-6);
        EXPECT_GE(d, half_width * std::cos(M_PI / (4.0 * o.arch_chords)) - 1e-6);
      }
    }
    // Sparse: the walls are plain almost everywhere, with a feature every 10-20 m.
    EXPECT_GT(plain, 0.85 * samples) << "seed " << seed;
    EXPECT_GE(features, static_cast<int>(o.length_m / o.feature_spacing_max_m) - 1) << "seed " << seed;
    EXPECT_LE(features, static_cast<int>(o.length_m / o.feature_spacing_min_m) + 1) << "seed " << seed;
  }
}

TEST(SimExtraScenes, StairsTreadsRisersAndLandings)
{
  const StairsOptions o;
  const double half_width = 0.5 * o.width_m;
  const Scene scene = stairsScene(3, o);
  const double above = 5.5;
  const auto floor_below = [&](double x)
  { return above - distanceAlong(scene, Eigen::Vector3d(x, 0.0, above), -Eigen::Vector3d::UnitZ()); };
  EXPECT_NEAR(floor_below(-2.0), 0.0, 1e-9);
  for (int i = 0; i + 1 < o.risers; ++i)
  {
    EXPECT_NEAR(floor_below((i + 0.5) * o.tread_m), (i + 1) * o.rise_m, 1e-9) << "tread " << i;
    // Riser i faces the climber: a horizontal ray just above the previous tread hits it.
    const double z = i * o.rise_m + 0.05;
    EXPECT_NEAR(distanceAlong(scene, Eigen::Vector3d(i * o.tread_m - 0.1, 0.0, z), Eigen::Vector3d::UnitX()), 0.1, 1e-9)
        << "riser " << i;
  }
  EXPECT_NEAR(floor_below(o.run() + 2.0), o.totalRise(), 1e-9);
  EXPECT_GT(o.totalRise(), 2.9);
  EXPECT_LT(o.run(), 5.0);
  // The stairwell's walls.
  for (double x = -3.0; x < o.run() + 4.0; x += 0.5)
  {
    const double z = floor_below(x) + 1.5;
    for (const double side : { -1.0, 1.0 })
    {
      const double d = distanceAlong(scene, Eigen::Vector3d(x, 0.0, z), Eigen::Vector3d(0.0, side, 0.0));
      EXPECT_LE(d, half_width + 1e-9) << "x " << x;
      EXPECT_GE(d, half_width - 0.5) << "x " << x;  // a cabinet at most
    }
  }
}

}  // namespace sim
}  // namespace aloam
