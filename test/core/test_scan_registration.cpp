// Tests of ScanRegistration on ray-cast street sweeps: rings and times, feature placement, limits, counters.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <string>
#include <variant>
#include <vector>

#include <gtest/gtest.h>

#include "aloam_nodelet/core/fast_atan2.h"
#include "aloam_nodelet/core/laser_odometry.h"
#include "aloam_nodelet/core/scan_registration.h"
#include "test_support.h"

namespace aloam
{
namespace
{
using test_support::makePoint;
namespace ts = test_support;

// Where the static sweeps are taken: on the centreline, a little rotated so nothing is axis-aligned.
constexpr double kSweepX = 60.0;
constexpr double kSweepY = 0.4;
constexpr double kSweepYaw = 0.05;
// Second start azimuth tried for the time-from-azimuth path (rad).
constexpr double kOtherStartAzimuth = 2.0;

// Feature placement criteria.
constexpr double kEdgeDistance = 0.3;      // a sharp point this close to a box edge lies on an edge (m)
constexpr double kClearOfObjects = 1.0;    // ground "far from any object" (m)
constexpr double kDepthJump = 1.0;         // range jump to a ring neighbour that marks an occluding edge (m)
constexpr int kDiscontinuityWindow = 5;    // ring neighbours inspected for a depth jump (the curvature window)
constexpr double kAdjacentBearing = 0.05;  // rad; consecutive points farther apart in bearing have a gap between
constexpr int kFlatWindow = 2;             // ring neighbours that must share a flat point's plane
constexpr double kMinSharpOnEdges = 0.8;
constexpr double kMaxSharpOnOpenGround = 0.01;
constexpr double kMinFlatOnPlanes = 0.95;

// Rings / times recovered without the fields.
constexpr double kMinRingAgreement = 0.99;
constexpr double kTimeTolerance = 0.002;  // s
constexpr double kMinTimeAgreement = 0.95;

// A-LOAM feature limits per sector, and sectors per ring.
constexpr int kSectors = 6;
constexpr int kMaxSharp = 2;
constexpr int kMaxLessSharp = 20;
constexpr int kMaxFlat = 4;

struct Sweep
{
  SensorModel sensor = *SensorModel::fromPreset("VLP16");
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  Cloud cloud;
  std::vector<int> surface_ids;
};

Sweep makeSweep(const std::string& preset, double start_azimuth = 0.0)
{
  Sweep s;
  s.sensor = ts::preset(preset);
  s.pose = ts::poseFrom(kSweepX, kSweepY, ts::kSensorHeight, kSweepYaw);
  s.cloud = ts::staticSweep(s.sensor, s.pose, &s.surface_ids, start_azimuth);
  return s;
}

// Sweeps are ray-cast once per process.
const Sweep& vlp16Sweep()
{
  static const Sweep sweep = makeSweep("VLP16");
  return sweep;
}

const Sweep& hdl64Sweep()
{
  static const Sweep sweep = makeSweep("HDL64");
  return sweep;
}

ScanRegistrationConfig configFor(const SensorModel& sensor)
{
  ScanRegistrationConfig config;
  config.sensor = sensor;
  config.scan_period = sensor.scanPeriod();
  return config;
}

FeatureSet extract(const Sweep& sweep, bool has_ring, bool has_time, const ScanRegistrationConfig& config)
{
  ScanRegistration registration(config);
  FeatureSet features;
  EXPECT_TRUE(registration.process(sweep.cloud, 1.0, has_ring, has_time, features));
  return features;
}

// Distance from a world point to the nearest of the 12 edges of a box.
double distanceToBoxEdge(const sim::OrientedBox& box, const Eigen::Vector3d& world)
{
  const Eigen::Vector3d d = world - box.center();
  const double c = std::cos(box.yaw()), s = std::sin(box.yaw());
  const Eigen::Vector3d local(c * d.x() + s * d.y(), -s * d.x() + c * d.y(), d.z());
  const Eigen::Vector3d a = local.cwiseAbs();
  const Eigen::Vector3d h = box.halfExtents();
  double best = std::numeric_limits<double>::infinity();
  for (int axis = 0; axis < 3; ++axis)
  {
    const int u = (axis + 1) % 3, v = (axis + 2) % 3;
    const double along = std::max(0.0, a[axis] - h[axis]);
    best = std::min(best, std::sqrt(std::pow(a[u] - h[u], 2) + std::pow(a[v] - h[v], 2) + along * along));
  }
  return best;
}

// Face of a box a surface point lies on (0..5).
int boxFace(const sim::OrientedBox& box, const Eigen::Vector3d& world)
{
  const Eigen::Vector3d d = world - box.center();
  const double c = std::cos(box.yaw()), s = std::sin(box.yaw());
  const Eigen::Vector3d local(c * d.x() + s * d.y(), -s * d.x() + c * d.y(), d.z());
  int axis = 0;
  double best = -1.0;
  for (int k = 0; k < 3; ++k)
  {
    const double r = std::fabs(local[k]) / box.halfExtents()[k];
    if (r > best)
    {
      best = r;
      axis = k;
    }
  }
  return 2 * axis + (local[axis] > 0.0 ? 1 : 0);
}

// Distance to the nearest edge of any box of the scene, and to the nearest pole / trunk surface.
double distanceToAnyBoxEdge(const sim::Scene& scene, const Eigen::Vector3d& world)
{
  double best = std::numeric_limits<double>::infinity();
  for (const sim::Primitive& p : scene.primitives())
  {
    if (const auto* box = std::get_if<sim::OrientedBox>(&p.shape))
    {
      best = std::min(best, distanceToBoxEdge(*box, world));
    }
  }
  return best;
}

double distanceToAnyCylinder(const sim::Scene& scene, const Eigen::Vector3d& world)
{
  double best = std::numeric_limits<double>::infinity();
  for (const sim::Primitive& p : scene.primitives())
  {
    if (const auto* cyl = std::get_if<sim::VerticalCylinder>(&p.shape))
    {
      const double radial = std::hypot(world.x() - cyl->centerX(), world.y() - cyl->centerY()) - cyl->radius();
      const double vertical = std::max({ 0.0, cyl->zMin() - world.z(), world.z() - cyl->zMax() });
      best = std::min(best, std::hypot(std::max(0.0, radial), vertical));
    }
  }
  return best;
}

double rangeOf(const Point& p)
{
  return std::sqrt(double(p.x) * p.x + double(p.y) * p.y + double(p.z) * p.z);
}

// Angle between the bearings of two points (rad).
double bearingBetween(const Point& a, const Point& b)
{
  const Eigen::Vector3d u(a.x, a.y, a.z), v(b.x, b.y, b.z);
  return std::acos(std::clamp(u.normalized().dot(v.normalized()), -1.0, 1.0));
}

// Surface id of every point of `full` (looked up in the ray-cast cloud by coordinates).
std::vector<int> surfaceIdsOf(const Cloud& full, const Sweep& sweep)
{
  const auto index = ts::indexByCoordinates(sweep.cloud);
  std::vector<int> ids(full.size(), -1);
  for (std::size_t i = 0; i < full.size(); ++i)
  {
    const auto it = index.find(ts::keyOf(full.points[i]));
    if (it != index.end())
    {
      ids[i] = sweep.surface_ids[it->second];
    }
  }
  return ids;
}

// Identifier of the plane a point lies on: the surface id, refined by the box face; -1 if not planar.
int planeIdOf(const sim::Scene& scene, int surface_id, const Eigen::Vector3d& world)
{
  if (surface_id < 0)
  {
    return -1;
  }
  const sim::Primitive& p = scene.primitive(surface_id);
  if (std::holds_alternative<sim::PlanePatch>(p.shape))
  {
    return 6 * surface_id;
  }
  if (const auto* box = std::get_if<sim::OrientedBox>(&p.shape))
  {
    return 6 * surface_id + boxFace(*box, world);
  }
  return -1;
}

struct PlacementFigures
{
  int sharp = 0;
  int sharp_on_edges = 0;
  int sharp_on_open_ground = 0;
  int sharp_far_side = 0;  // beside a depth jump, on its far side
  int sharp_shadow = 0;    // ... of a jump to another object, and on no edge of its own surface: the
                           // moving edge of an occlusion shadow
  int flat = 0;
  int flat_on_planes = 0;
};

// Classifies every sharp and flat point against the scene's ground truth.
PlacementFigures placement(const Sweep& sweep, const FeatureSet& f)
{
  const sim::Scene& scene = ts::streetScene();
  const std::vector<int> ids = surfaceIdsOf(f.full, sweep);
  const auto full_index = ts::indexByCoordinates(f.full);
  const auto world = [&](const Point& p) { return sweep.pose * Eigen::Vector3d(p.x, p.y, p.z); };
  // Index of a feature point in the full cloud, or -1.
  const auto indexInFull = [&](const Point& p)
  {
    const auto it = full_index.find(ts::keyOf(p));
    return it == full_index.end() ? -1 : static_cast<int>(it->second);
  };
  const std::vector<int> begins = ringBegins(f.full);
  const auto ringRange = [&](int i)
  {
    const int r = f.full.points[static_cast<std::size_t>(i)].ring;
    return std::make_pair(begins[static_cast<std::size_t>(r)], begins[static_cast<std::size_t>(r) + 1]);
  };

  PlacementFigures fig;
  for (const Point& p : f.sharp.points)
  {
    ++fig.sharp;
    const int i = indexInFull(p);
    if (i < 0)
    {
      continue;
    }
    const auto [lo, hi] = ringRange(i);
    // A depth jump between two angularly adjacent points of the curvature window: the point borders an
    // occluding edge, on its near or far side.
    bool discontinuity = false, far_side = false, behind_other = false;
    for (int k = std::max(lo, i - kDiscontinuityWindow); k < std::min(hi - 1, i + kDiscontinuityWindow); ++k)
    {
      const Point& a = f.full.points[static_cast<std::size_t>(k)];
      const Point& b = f.full.points[static_cast<std::size_t>(k) + 1];
      const double jump = rangeOf(b) - rangeOf(a);
      if (std::fabs(jump) <= kDepthJump || bearingBetween(a, b) > kAdjacentBearing)
      {
        continue;
      }
      discontinuity = true;
      // p is on b's side when the pair lies before it, on a's side otherwise.
      const bool beyond = k + 1 <= i ? jump > 0.0 : jump < 0.0;
      far_side = far_side || beyond;
      // ... and the jump is to another object (not one surface at a grazing angle).
      behind_other =
          behind_other || (beyond && ids[static_cast<std::size_t>(k)] != ids[static_cast<std::size_t>(k) + 1]);
    }
    fig.sharp_far_side += far_side ? 1 : 0;
    const Eigen::Vector3d w = world(p);
    const int id = ids[static_cast<std::size_t>(i)];
    const sim::SurfaceClass cls = id >= 0 ? scene.primitive(id).surface_class : sim::SurfaceClass::Other;
    const bool thin = cls == sim::SurfaceClass::Pole || cls == sim::SurfaceClass::TreeTrunk;
    const double edge = distanceToAnyBoxEdge(scene, w);
    if (thin || edge <= kEdgeDistance || discontinuity)
    {
      ++fig.sharp_on_edges;
    }
    fig.sharp_shadow += behind_other && !thin && edge > kEdgeDistance ? 1 : 0;
    const bool open_ground = id >= 0 && std::holds_alternative<sim::PlanePatch>(scene.primitive(id).shape) &&
                             edge > kClearOfObjects && distanceToAnyCylinder(scene, w) > kClearOfObjects &&
                             !discontinuity;
    fig.sharp_on_open_ground += open_ground ? 1 : 0;
  }

  for (const Point& p : f.flat.points)
  {
    ++fig.flat;
    const int i = indexInFull(p);
    if (i < 0)
    {
      continue;
    }
    const auto [lo, hi] = ringRange(i);
    if (i - kFlatWindow < lo || i + kFlatWindow >= hi)
    {
      continue;
    }
    const int plane = planeIdOf(scene, ids[static_cast<std::size_t>(i)], world(p));
    bool same = plane >= 0;
    for (int k = i - kFlatWindow; same && k <= i + kFlatWindow; ++k)
    {
      const Point& q = f.full.points[static_cast<std::size_t>(k)];
      same = planeIdOf(scene, ids[static_cast<std::size_t>(k)], world(q)) == plane;
    }
    fig.flat_on_planes += same ? 1 : 0;
  }
  return fig;
}

// Structural invariants every FeatureSet must satisfy.
void expectWellFormed(const FeatureSet& f, int num_rings)
{
  EXPECT_TRUE(f.has_time);
  EXPECT_GT(f.sharp.size(), 0u);
  EXPECT_GT(f.flat.size(), 0u);
  EXPECT_GE(f.less_sharp.size(), f.sharp.size());
  EXPECT_GT(f.less_flat.size(), f.flat.size());
  EXPECT_EQ(f.stats.points_used, f.full.size());
  EXPECT_EQ(f.stats.rings, num_rings);

  for (const Cloud* c : { &f.sharp, &f.less_sharp, &f.flat, &f.less_flat, &f.full })
  {
    EXPECT_TRUE(ts::ringOrdered(*c));
    EXPECT_TRUE(ts::allFinite(*c));
    EXPECT_EQ(c->width, c->size());
    for (const Point& p : c->points)
    {
      ASSERT_LT(p.ring, num_rings);
      ASSERT_GE(p.time, 0.0f);
      ASSERT_LE(p.time, static_cast<float>(f.scan_period));
    }
  }

  // Per-sector limits, checked per ring (6 sectors) and globally.
  std::vector<int> sharp(static_cast<std::size_t>(num_rings)), less_sharp(sharp), flat(sharp);
  for (const Point& p : f.sharp.points)
  {
    ++sharp[p.ring];
  }
  for (const Point& p : f.less_sharp.points)
  {
    ++less_sharp[p.ring];
  }
  for (const Point& p : f.flat.points)
  {
    ++flat[p.ring];
  }
  for (int r = 0; r < num_rings; ++r)
  {
    EXPECT_LE(sharp[static_cast<std::size_t>(r)], kSectors * kMaxSharp) << "ring " << r;
    EXPECT_LE(less_sharp[static_cast<std::size_t>(r)], kSectors * kMaxLessSharp) << "ring " << r;
    EXPECT_LE(flat[static_cast<std::size_t>(r)], kSectors * kMaxFlat) << "ring " << r;
  }
  EXPECT_LE(f.sharp.size(), static_cast<std::size_t>(num_rings * kSectors * kMaxSharp));
  EXPECT_LE(f.less_sharp.size(), static_cast<std::size_t>(num_rings * kSectors * kMaxLessSharp));
  EXPECT_LE(f.flat.size(), static_cast<std::size_t>(num_rings * kSectors * kMaxFlat));

  // less_sharp contains every sharp point; every feature point is a point of the full cloud.
  const auto less_sharp_index = ts::indexByCoordinates(f.less_sharp);
  const auto full_index = ts::indexByCoordinates(f.full);
  int sharp_missing = 0, not_in_full = 0;
  for (const Point& p : f.sharp.points)
  {
    sharp_missing += less_sharp_index.count(ts::keyOf(p)) == 0 ? 1 : 0;
  }
  for (const Cloud* c : { &f.sharp, &f.less_sharp, &f.flat })
  {
    for (const Point& p : c->points)
    {
      not_in_full += full_index.count(ts::keyOf(p)) == 0 ? 1 : 0;
    }
  }
  EXPECT_EQ(sharp_missing, 0);
  EXPECT_EQ(not_in_full, 0);

  // less_flat is a voxel-filtered superset of flat: each flat point has a less-flat centroid of its ring
  // in its voxel, hence within a voxel diagonal.
  const double reach_sq = 3.0 * 0.2 * 0.2;
  int flat_unrepresented = 0;
  for (const Point& p : f.flat.points)
  {
    bool found = false;
    for (const Point& q : f.less_flat.points)
    {
      const double dx = p.x - q.x, dy = p.y - q.y, dz = p.z - q.z;
      if (q.ring == p.ring && dx * dx + dy * dy + dz * dz <= reach_sq)
      {
        found = true;
        break;
      }
    }
    flat_unrepresented += found ? 0 : 1;
  }
  EXPECT_EQ(flat_unrepresented, 0);
}

// Features of a sweep lie where LOAM expects them and satisfy every structural invariant.
PlacementFigures checkFeaturePlacement(const Sweep& sweep, bool has_fields, const ScanRegistrationConfig& config)
{
  const FeatureSet f = extract(sweep, has_fields, has_fields, config);
  expectWellFormed(f, sweep.sensor.numRings());
  const PlacementFigures fig = placement(sweep, f);
  std::printf(
      "[ measured ] %s fields=%d reject_occluded=%d: %d sharp, %.1f %% on edges, %d on open ground, %d far side "
      "(%d shadow edges); %d flat, %.1f %% on planes\n",
      sweep.sensor.name().c_str(), has_fields ? 1 : 0, config.reject_occluded ? 1 : 0, fig.sharp,
      100.0 * fig.sharp_on_edges / fig.sharp, fig.sharp_on_open_ground, fig.sharp_far_side, fig.sharp_shadow, fig.flat,
      100.0 * fig.flat_on_planes / fig.flat);
  EXPECT_GT(fig.sharp, 0);
  EXPECT_GT(fig.flat, 0);
  EXPECT_GE(fig.sharp_on_edges, kMinSharpOnEdges * fig.sharp);
  EXPECT_LE(fig.sharp_on_open_ground, kMaxSharpOnOpenGround * fig.sharp);
  EXPECT_GE(fig.flat_on_planes, kMinFlatOnPlanes * fig.flat);
  return fig;
}

// Rings from elevation and times from azimuth agree with the simulator's true rings and times.
void checkRingsAndTimesWithoutFields(const Sweep& sweep)
{
  const FeatureSet f = extract(sweep, false, false, configFor(sweep.sensor));
  const auto truth = ts::indexByCoordinates(sweep.cloud);
  std::size_t found = 0, ring_ok = 0, time_ok = 0;
  for (const Point& p : f.full.points)
  {
    const auto it = truth.find(ts::keyOf(p));
    if (it == truth.end())
    {
      continue;
    }
    ++found;
    const Point& t = sweep.cloud.points[it->second];
    ring_ok += p.ring == t.ring ? 1 : 0;
    time_ok += std::fabs(double(p.time) - double(t.time)) <= kTimeTolerance ? 1 : 0;
  }
  std::printf("[ measured ] %s without fields: %zu points, rings %.3f %% right, times %.3f %% within %.0f ms\n",
              sweep.sensor.name().c_str(), found, 100.0 * ring_ok / found, 100.0 * time_ok / found,
              1e3 * kTimeTolerance);
  EXPECT_EQ(found, f.full.size());
  EXPECT_GE(found, sweep.cloud.size() * 9 / 10);
  EXPECT_GE(ring_ok, kMinRingAgreement * found);
  EXPECT_GE(time_ok, kMinTimeAgreement * found);
}

}  // namespace

// VLP16 with ring and time fields (default configuration): sharp points on edges, flat points on planes,
// all invariants hold.
TEST(ScanRegistrationTest, Vlp16FeaturesWithFields)
{
  checkFeaturePlacement(vlp16Sweep(), true, configFor(vlp16Sweep().sensor));
}

// VLP16 without ring and time fields: the same guarantees with rings and times recovered.
TEST(ScanRegistrationTest, Vlp16FeaturesWithoutFields)
{
  checkFeaturePlacement(vlp16Sweep(), false, configFor(vlp16Sweep().sensor));
}

// HDL64 (non-uniform table) with and without fields: the same guarantees on 64 rings.
TEST(ScanRegistrationTest, Hdl64FeaturesWithAndWithoutFields)
{
  checkFeaturePlacement(hdl64Sweep(), true, configFor(hdl64Sweep().sensor));
  checkFeaturePlacement(hdl64Sweep(), false, configFor(hdl64Sweep().sensor));
}

// Without fields, rings from elevation and times from azimuth match the truth (VLP16 and HDL64).
TEST(ScanRegistrationTest, RingsAndTimesRecoveredWithoutFields)
{
  checkRingsAndTimesWithoutFields(vlp16Sweep());
  checkRingsAndTimesWithoutFields(hdl64Sweep());
}

// The time recovery does not depend on where the sweep starts: a start azimuth of 2 rad works too.
TEST(ScanRegistrationTest, TimesRecoveredForArbitraryStartAzimuth)
{
  const Sweep sweep = makeSweep("VLP16", kOtherStartAzimuth);
  checkRingsAndTimesWithoutFields(sweep);
}

// Occlusion rejection (original LOAM, off in A-LOAM) removes the sharp points behind occluding edges.
TEST(ScanRegistrationTest, OcclusionRejectionRemovesFarSideEdges)
{
  ScanRegistrationConfig config = configFor(vlp16Sweep().sensor);
  config.reject_occluded = false;
  const PlacementFigures plain = checkFeaturePlacement(vlp16Sweep(), true, config);
  config.reject_occluded = true;
  config.occlusion_continuity = 0.0;
  const PlacementFigures every_gap = checkFeaturePlacement(vlp16Sweep(), true, config);
  config.occlusion_continuity = 0.15;
  const PlacementFigures rejecting = checkFeaturePlacement(vlp16Sweep(), true, config);
  // Without rejection a street sweep has edge points on the moving edges of shadows behind cars, poles
  // and facade steps; with it (almost) none, whether or not continuous gaps are exempt.
  EXPECT_GT(plain.sharp_shadow, 0);
  EXPECT_LE(every_gap.sharp_shadow, kMaxSharpOnOpenGround * every_gap.sharp);
  EXPECT_LE(rejecting.sharp_shadow, kMaxSharpOnOpenGround * rejecting.sharp);
  // Gaps that a surface runs on across (concave corners, grazing walls) keep their real edges: more far-side
  // points on real edges than LOAM's rule, which marks every gap, keeps.
  EXPECT_GT(rejecting.sharp_far_side - rejecting.sharp_shadow, every_gap.sharp_far_side - every_gap.sharp_shadow);
}

// A VLP-16 sweep down an empty corridor (walls at y = +-1.25 m, floor and ceiling at z = -+1.5 m, open
// ends): every return lies on a plane, but along a wall seen at a grazing angle the returns spread apart
// faster and faster, which raises LOAM's curvature there. Such a point is no edge for mapping:
// curvature_across_ring keeps it out of FeatureSet::bending, while the corners where walls meet floor and
// ceiling stay in; odometry's edges (less_sharp) stay LOAM's.
TEST(ScanRegistrationTest, GrazingWallsGiveNoEdgesCornersDo)
{
  constexpr double kHalfWidth = 1.25, kHalfHeight = 1.5, kAzimuthStepDeg = 0.2, kCorner = 0.15;
  const SensorModel sensor = ts::preset("VLP16");
  Cloud cloud;
  for (double azimuth_deg = 0.0; azimuth_deg < 360.0; azimuth_deg += kAzimuthStepDeg)
  {
    for (const double elevation_deg : sensor.elevationsDeg())
    {
      const double a = azimuth_deg * M_PI / 180.0, e = elevation_deg * M_PI / 180.0;
      const Eigen::Vector3d ray(std::cos(e) * std::cos(a), std::cos(e) * std::sin(a), std::sin(e));
      double range = std::numeric_limits<double>::infinity();
      if (std::fabs(ray.y()) > 1e-9)
      {
        range = std::min(range, kHalfWidth / std::fabs(ray.y()));
      }
      if (std::fabs(ray.z()) > 1e-9)
      {
        range = std::min(range, kHalfHeight / std::fabs(ray.z()));
      }
      if (range < 100.0)
      {
        const Eigen::Vector3d p = range * ray;
        cloud.push_back(makePoint(p.x(), p.y(), p.z()));
      }
    }
  }
  // A sharp point on a wall face, away from the floor and ceiling corners.
  const auto on_wall_face = [&](const Point& p)
  { return std::fabs(std::fabs(p.y) - kHalfWidth) < 1e-3 && std::fabs(p.z) < kHalfHeight - kCorner; };
  const auto count = [&](const Cloud& edges, int& face, int& corner)
  {
    face = corner = 0;
    for (const Point& p : edges.points)
    {
      face += on_wall_face(p) ? 1 : 0;
      corner += std::fabs(std::fabs(p.y) - kHalfWidth) < kCorner && std::fabs(std::fabs(p.z) - kHalfHeight) < kCorner;
    }
  };
  ScanRegistrationConfig config = configFor(sensor);
  config.curvature_across_ring = false;
  FeatureSet loam;
  ASSERT_TRUE(ScanRegistration(config).process(cloud, 1.0, false, false, loam));
  EXPECT_FALSE(loam.bending.has_value());  // mapping then takes less_sharp
  config.curvature_across_ring = true;
  FeatureSet features;
  ASSERT_TRUE(ScanRegistration(config).process(cloud, 1.0, false, false, features));
  ASSERT_TRUE(features.bending.has_value());
  // Odometry's edges are LOAM's either way.
  EXPECT_EQ(features.less_sharp.size(), loam.less_sharp.size());
  EXPECT_EQ(features.sharp.size(), loam.sharp.size());
  int face_loam = 0, corner_loam = 0, face = 0, corner = 0;
  count(loam.less_sharp, face_loam, corner_loam);
  count(*features.bending, face, corner);
  EXPECT_GT(face_loam, 50) << "LOAM's curvature alone should find edges on the grazing walls";
  std::printf(
      "[ measured ] grazing corridor walls: mapping's edge points on the wall faces %d (LOAM's curvature %d), "
      "at the corners %d (%d)\n",
      face, face_loam, corner, corner_loam);
  EXPECT_LE(face, face_loam / 5);
  EXPECT_GT(corner, corner_loam / 2);
  // Every bending edge is one of less_sharp's.
  std::size_t found = 0;
  const auto all = ts::indexByCoordinates(features.less_sharp);
  for (const Point& p : features.bending->points)
  {
    found += all.count(ts::keyOf(p));
  }
  EXPECT_EQ(found, features.bending->size());
}

// With fields, the output carries exactly the input's rings and times.
TEST(ScanRegistrationTest, FieldsArePassedThrough)
{
  const Sweep& sweep = vlp16Sweep();
  const FeatureSet f = extract(sweep, true, true, configFor(sweep.sensor));
  const auto truth = ts::indexByCoordinates(sweep.cloud);
  int mismatched = 0;
  for (const Point& p : f.full.points)
  {
    const auto it = truth.find(ts::keyOf(p));
    ASSERT_NE(it, truth.end());
    const Point& t = sweep.cloud.points[it->second];
    mismatched += p.ring != t.ring || p.time != t.time ? 1 : 0;
  }
  EXPECT_EQ(mismatched, 0);
  EXPECT_EQ(f.stats.points_in, sweep.cloud.size());
  EXPECT_DOUBLE_EQ(f.stamp, 1.0);
}

// An Ouster sweep as ouster_ros publishes it (ring = image row, row 0 = highest beam): with the OS1_64
// preset every output point lands on the ring its elevation gives, counted from the lowest beam.
TEST(ScanRegistrationTest, OusterRingFieldCountsFromTheTop)
{
  Sweep sweep = makeSweep("OS1_64");
  const int rings = sweep.sensor.numRings();
  for (Point& p : sweep.cloud.points)
  {
    p.ring = static_cast<std::uint16_t>(rings - 1 - p.ring);
  }
  const FeatureSet f = extract(sweep, true, true, configFor(sweep.sensor));
  ASSERT_FALSE(f.full.empty());
  int mismatched = 0;
  for (const Point& p : f.full.points)
  {
    const double elevation = std::atan2(double(p.z), std::hypot(double(p.x), double(p.y)));
    mismatched += int(p.ring) != sweep.sensor.ringForElevation(elevation) ? 1 : 0;
  }
  EXPECT_EQ(mismatched, 0) << "of " << f.full.size() << " points";
  EXPECT_EQ(f.stats.rings, rings);
}

// Crafted bad points are counted: NaN/Inf in `invalid`, too close / too far in `out_of_range`, off-table
// elevations (or ring fields past the limit) in `unassigned_ring`; none reaches the output.
TEST(ScanRegistrationTest, StatsCountRejectedPoints)
{
  const Sweep& sweep = vlp16Sweep();
  constexpr int kNan = 7, kInf = 5, kTooClose = 11, kTooFar = 13, kOffTable = 17;
  constexpr double kOffTableElevationDeg = 40.0;
  constexpr double kOffTableRange = 10.0;
  constexpr double kFarRange = 250.0;  // beyond the default maximum_range of 200 m
  constexpr double kCloseRange = 0.1;  // below the default minimum_range of 0.3 m
  constexpr std::uint16_t kBadRingField = 300;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();

  Cloud crafted = sweep.cloud;
  for (int i = 0; i < kNan; ++i)
  {
    Point p = makePoint(5.0, 1.0, 0.0, 3);
    (i % 3 == 0 ? p.x : i % 3 == 1 ? p.y : p.z) = nan;
    crafted.push_back(p);
  }
  for (int i = 0; i < kInf; ++i)
  {
    Point p = makePoint(5.0, 1.0, 0.0, 3);
    p.y = i % 2 == 0 ? inf : -inf;
    crafted.push_back(p);
  }
  for (int i = 0; i < kTooClose; ++i)
  {
    crafted.push_back(makePoint(kCloseRange * std::cos(i), kCloseRange * std::sin(i), 0.0, 3));
  }
  for (int i = 0; i < kTooFar; ++i)
  {
    crafted.push_back(makePoint(kFarRange * std::cos(i), kFarRange * std::sin(i), 0.0, 3));
  }
  const double e = kOffTableElevationDeg * ts::kDegToRad;
  for (int i = 0; i < kOffTable; ++i)
  {
    crafted.push_back(makePoint(kOffTableRange * std::cos(e) * std::cos(i), kOffTableRange * std::cos(e) * std::sin(i),
                                kOffTableRange * std::sin(e), kBadRingField));
  }

  for (const bool has_ring : { false, true })
  {
    ScanRegistration registration(configFor(sweep.sensor));
    FeatureSet f;
    ASSERT_TRUE(registration.process(crafted, 0.0, has_ring, true, f));
    EXPECT_EQ(f.stats.points_in, crafted.size());
    EXPECT_EQ(f.stats.invalid, static_cast<std::size_t>(kNan + kInf));
    EXPECT_EQ(f.stats.out_of_range, static_cast<std::size_t>(kTooClose + kTooFar));
    EXPECT_EQ(f.stats.unassigned_ring, static_cast<std::size_t>(kOffTable));
    EXPECT_EQ(f.stats.points_used, sweep.cloud.size());
    EXPECT_EQ(f.full.size(), sweep.cloud.size());
    EXPECT_TRUE(ts::allFinite(f.full));
    EXPECT_EQ(f.stats.rings, sweep.sensor.numRings());
  }
}

// The threads share the input in blocks and the rings in groups that depend on the thread count: the
// features must not. Every cloud equal point for point at 1 to 5 threads, with and without the fields
// (times from azimuth: the spin direction is summed per ring), for a sweep starting at two azimuths.
TEST(ScanRegistrationTest, ThreadsDoNotChangeTheFeatures)
{
  const auto same = [](const Cloud& a, const Cloud& b)
  {
    if (a.size() != b.size())
    {
      return false;
    }
    for (std::size_t i = 0; i < a.size(); ++i)
    {
      const Point &p = a.points[i], &q = b.points[i];
      if (p.x != q.x || p.y != q.y || p.z != q.z || p.time != q.time || p.ring != q.ring || p.intensity != q.intensity)
      {
        return false;
      }
    }
    return true;
  };
  for (const Sweep* sweep : { &vlp16Sweep(), &hdl64Sweep() })
  {
    const Sweep turned = makeSweep(sweep == &vlp16Sweep() ? "VLP16" : "HDL64", kOtherStartAzimuth);
    for (const Sweep* s : { sweep, &turned })
    {
      for (const bool fields : { true, false })
      {
        ScanRegistrationConfig config = configFor(s->sensor);
        config.threads = 1;
        const FeatureSet one = extract(*s, fields, fields, config);
        ASSERT_GT(one.sharp.size(), 0u);
        for (int threads = 2; threads <= 5; ++threads)
        {
          config.threads = threads;
          const FeatureSet many = extract(*s, fields, fields, config);
          const std::string what = s->sensor.name() + (fields ? " with fields, " : " without fields, ") +
                                   std::to_string(threads) + " threads";
          EXPECT_TRUE(same(one.full, many.full)) << what;
          EXPECT_TRUE(same(one.sharp, many.sharp)) << what;
          EXPECT_TRUE(same(one.less_sharp, many.less_sharp)) << what;
          EXPECT_TRUE(same(one.flat, many.flat)) << what;
          EXPECT_TRUE(same(one.less_flat, many.less_flat)) << what;
          EXPECT_EQ(one.stats.occluded, many.stats.occluded) << what;
          EXPECT_EQ(one.stats.grazing, many.stats.grazing) << what;
          EXPECT_EQ(one.stats.rings, many.stats.rings) << what;
        }
      }
    }
  }
}

// Too few usable points: process returns false with empty clouds, and the counters still add up.
TEST(ScanRegistrationTest, TooFewPointsGiveEmptyOutput)
{
  ScanRegistration registration(configFor(ts::preset("VLP16")));
  Cloud tiny;
  for (int i = 0; i < 5; ++i)
  {
    tiny.push_back(makePoint(10.0, 0.1 * i, 0.0, 8));
  }
  FeatureSet f;
  f.sharp.push_back(makePoint(1.0, 1.0, 1.0, 0));  // stale content must be cleared
  EXPECT_FALSE(registration.process(tiny, 3.0, true, true, f));
  EXPECT_TRUE(f.full.empty());
  EXPECT_TRUE(f.sharp.empty());
  EXPECT_TRUE(f.less_flat.empty());
  EXPECT_EQ(f.stats.points_in, 5u);
}

}  // namespace aloam

namespace aloam
{
namespace
{
// The azimuths of the registration: within 4e-8 rad of std::atan2 everywhere, quadrants and axes right.
TEST(FastAtan2, WithinFortyNanoradiansOfAtan2)
{
  std::mt19937 rng(13);
  std::uniform_real_distribution<double> coordinate(-100.0, 100.0);
  std::uniform_real_distribution<double> tiny(-1e-3, 1e-3);
  double worst = 0.0;
  for (int k = 0; k < 1'000'000; ++k)
  {
    const double x = k % 4 == 3 ? tiny(rng) : coordinate(rng);
    const double y = coordinate(rng);
    worst = std::max(worst, std::fabs(fastAtan2(y, x) - std::atan2(y, x)));
  }
  EXPECT_LT(worst, 4e-8);
  EXPECT_GT(worst, 0.0);  // an approximation, not std::atan2 itself
  for (const auto& [y, x] : std::vector<std::pair<double, double>>{ { 0.0, 1.0 },
                                                                    { 1.0, 0.0 },
                                                                    { 0.0, -1.0 },
                                                                    { -1.0, 0.0 },
                                                                    { 1.0, 1.0 },
                                                                    { -1.0, -1.0 },
                                                                    { -0.0, -1.0 },
                                                                    { 0.0, 0.0 },
                                                                    { -0.0, -0.0 },
                                                                    { 1e-300, -1.0 },
                                                                    { 5.0, std::numeric_limits<double>::infinity() } })
  {
    EXPECT_NEAR(fastAtan2(y, x), std::atan2(y, x), 4e-8) << y << ", " << x;
    EXPECT_EQ(std::signbit(fastAtan2(y, x)), std::signbit(std::atan2(y, x))) << y << ", " << x;
  }
  EXPECT_TRUE(std::isnan(fastAtan2(std::numeric_limits<double>::quiet_NaN(), 1.0)));
  EXPECT_TRUE(std::isnan(fastAtan2(1.0, std::numeric_limits<double>::quiet_NaN())));
}

}  // namespace
}  // namespace aloam
