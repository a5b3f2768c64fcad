#include "aloam_nodelet/sim/scenes_extra.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <utility>
#include <vector>

#include "deterministic_rng.h"

namespace aloam
{
namespace sim
{
namespace
{
constexpr int kChordsPerVerticalCurve = 4;  // chords approximating each rounded kink of the hill
constexpr double kBreakpointTolerance = 1e-9;
constexpr double kDoorHeight = 2.1;           // metres
constexpr double kDoorBackThickness = 0.1;    // metres, the door leaf behind the recess
constexpr double kNicheWidth = 1.5;           // metres
constexpr double kNicheDepth = 0.6;           // metres
constexpr double kCorridorFloorMargin = 2.0;  // metres, floor and ceiling run past the walls
constexpr double kLightHalfExtentX = 0.3;
constexpr double kLightHalfExtentY = 0.15;
constexpr double kLightHalfExtentZ = 0.05;
constexpr double kFieldGroundMargin = 200.0;
constexpr double kFieldFirstObjectX = 20.0;
constexpr double kFieldMinLateral = 8.0;
constexpr double kFieldLateralSpan = 20.0;
constexpr double kPi = 3.14159265358979323846;
// Office clutter (cabinets against the walls).
constexpr double kClutterMinStretch = 1.6;  // metres of plain wall needed for a cabinet
constexpr double kClutterMargin = 0.2;
constexpr double kClutterLengthMin = 0.5;
constexpr double kClutterLengthMax = 1.2;
constexpr double kClutterDepthMin = 0.3;
constexpr double kClutterHeightMin = 0.8;
constexpr double kClutterHeightMax = 2.0;
// Tunnel.
constexpr double kTunnelEndMargin = 20.0;  // metres of tunnel beyond the last feature
constexpr double kTunnelNicheShare = 0.35;
constexpr double kTunnelLightShare = 0.35;  // the rest are standpipes
constexpr double kTunnelLightHalfLength = 0.6;
constexpr double kTunnelLightHalfDepth = 0.1;
constexpr double kTunnelLightHalfHeight = 0.08;
constexpr double kStandpipeRadius = 0.1;
constexpr double kCableTrayWidth = 0.3;
constexpr double kCableTrayHeight = 0.1;
constexpr double kCableTrayZ = 2.3;
// Stairwell.
constexpr double kStairsBlend = 1.0;  // metres, rounding of the walking surface at the flight's ends
constexpr double kStairsDoorWidth = 0.9;
constexpr double kStairsDoorProud = 0.05;
constexpr double kStairsLampHalfDepth = 0.06;

/// Planar patches following `profile` over [x_min, x_max] x [y_min, y_max], raised by `base_z`.
std::vector<PlanePatch> profilePatches(const GroundProfile& profile, double base_z, double x_min, double x_max,
                                       double y_min, double y_max)
{
  std::vector<double> xs = { x_min, x_max };
  const double half_blend = 0.5 * profile.blend_length_m;
  for (const double kink : { profile.start_x, profile.start_x + profile.length_m })
  {
    for (int i = 0; i <= kChordsPerVerticalCurve; ++i)
    {
      xs.push_back(kink - half_blend + 2.0 * half_blend * i / kChordsPerVerticalCurve);
    }
  }
  std::sort(xs.begin(), xs.end());
  std::vector<double> breakpoints;
  for (const double x : xs)
  {
    if (x < x_min || x > x_max)
    {
      continue;
    }
    if (breakpoints.empty() || x - breakpoints.back() > kBreakpointTolerance)
    {
      breakpoints.push_back(x);
    }
  }
  std::vector<PlanePatch> patches;
  for (std::size_t i = 0; i + 1 < breakpoints.size(); ++i)
  {
    const double a = breakpoints[i];
    const double c = breakpoints[i + 1];
    const double slope = (profile.heightAt(c) - profile.heightAt(a)) / (c - a);
    const double offset = base_z + profile.heightAt(a) - slope * a;
    patches.emplace_back(slope, 0.0, offset, a, c, y_min, y_max);
  }
  return patches;
}

/// Lifts a shape by dz.
Shape lifted(const Shape& shape, double dz)
{
  if (const auto* box = std::get_if<OrientedBox>(&shape))
  {
    return OrientedBox(box->center() + Eigen::Vector3d(0.0, 0.0, dz), box->halfExtents(), box->yaw());
  }
  if (const auto* cylinder = std::get_if<VerticalCylinder>(&shape))
  {
    return VerticalCylinder(cylinder->centerX(), cylinder->centerY(), cylinder->radius(), cylinder->zMin() + dz,
                            cylinder->zMax() + dz);
  }
  if (const auto* sphere = std::get_if<Sphere>(&shape))
  {
    return Sphere(sphere->center() + Eigen::Vector3d(0.0, 0.0, dz), sphere->radius());
  }
  const auto& patch = std::get<PlanePatch>(shape);
  const Aabb box = patch.bounds();
  const double slope_x = patch.heightAt(1.0, 0.0) - patch.heightAt(0.0, 0.0);
  const double slope_y = patch.heightAt(0.0, 1.0) - patch.heightAt(0.0, 0.0);
  return PlanePatch(slope_x, slope_y, patch.heightAt(0.0, 0.0) + dz, box.min.x(), box.max.x(), box.min.y(),
                    box.max.y());
}

OrientedBox boxFromCorners(double x0, double x1, double y0, double y1, double z0, double z1)
{
  const Eigen::Vector3d lo(std::min(x0, x1), std::min(y0, y1), std::min(z0, z1));
  const Eigen::Vector3d hi(std::max(x0, x1), std::max(y0, y1), std::max(z0, z1));
  return OrientedBox(0.5 * (lo + hi), 0.5 * (hi - lo));
}
/// One corridor wall with openings, in the wall's own coordinates: u along it, v across it.
struct WallLayout
{
  bool along_y = false;  // the wall runs along y (u = y, v = x) instead of along x (u = x, v = y)
  double face_v = 0.0;   // v of the face towards the corridor
  double outward = 1.0;  // +1 or -1: the direction of v from the corridor into the wall
  double u_start = 0.0;
  double u_end = 0.0;
  double first_center = 0.0;  // u of the first opening's center
};

/// What a corridor wall is made of.
struct WallFeatures
{
  double height_m = 3.0;
  double wall_thickness_m = 0.4;
  double feature_spacing_m = 8.0;
  double spacing_jitter_m = 1.5;
  double door_width_m = 1.0;
  double recess_depth_m = 0.3;
  double clutter_probability = 0.0;  // 0: no cabinets (and no random numbers drawn for them)
  double clutter_depth_max_m = 0.5;
  bool close_niches = false;       // side walls between the wall's back and the niche's back
  double niche_probability = 0.3;  // a feature is a full-height niche instead of a door
};

void addBox(Scene& scene, const WallLayout& wall, double u0, double u1, double v0, double v1, double z0, double z1,
            SurfaceClass surface_class)
{
  if (wall.along_y)
  {
    scene.add(boxFromCorners(v0, v1, u0, u1, z0, z1), surface_class);
  }
  else
  {
    scene.add(boxFromCorners(u0, u1, v0, v1, z0, z1), surface_class);
  }
}

/// A solid stretch of wall over [u0, u1], maybe with a cabinet standing against it.
void addWallStretch(Scene& scene, DeterministicRng& rng, const WallFeatures& f, const WallLayout& wall, double u0,
                    double u1)
{
  const double back = wall.face_v + wall.outward * f.wall_thickness_m;
  addBox(scene, wall, u0, u1, wall.face_v, back, 0.0, f.height_m, SurfaceClass::Building);
  if (f.clutter_probability <= 0.0 || u1 - u0 < kClutterMinStretch || !rng.bernoulli(f.clutter_probability))
  {
    return;
  }
  const double length = rng.uniform(kClutterLengthMin, std::min(kClutterLengthMax, u1 - u0 - 2.0 * kClutterMargin));
  const double start = rng.uniform(u0 + kClutterMargin, u1 - kClutterMargin - length);
  const double depth = rng.uniform(kClutterDepthMin, std::max(kClutterDepthMin, f.clutter_depth_max_m));
  const double height = rng.uniform(kClutterHeightMin, kClutterHeightMax);
  addBox(scene, wall, start, start + length, wall.face_v - wall.outward * depth, wall.face_v, 0.0, height,
         SurfaceClass::Other);
}

/// What fills the opening [gap_start, gap_end] of a wall: a full-height niche or a recessed door.
void addOpening(Scene& scene, const WallFeatures& f, const WallLayout& wall, bool niche, double gap_start,
                double gap_end)
{
  const double face = wall.face_v;
  const double back = face + wall.outward * f.wall_thickness_m;
  if (niche)
  {
    const double niche_back = face + wall.outward * kNicheDepth;
    addBox(scene, wall, gap_start, gap_end, niche_back, niche_back + wall.outward * f.wall_thickness_m, 0.0, f.height_m,
           SurfaceClass::Building);
    if (f.close_niches)
    {
      addBox(scene, wall, gap_start - kDoorBackThickness, gap_start, back, niche_back, 0.0, f.height_m,
             SurfaceClass::Building);
      addBox(scene, wall, gap_end, gap_end + kDoorBackThickness, back, niche_back, 0.0, f.height_m,
             SurfaceClass::Building);
    }
  }
  else
  {
    const double door = face + wall.outward * f.recess_depth_m;
    addBox(scene, wall, gap_start, gap_end, door, door + wall.outward * kDoorBackThickness, 0.0, kDoorHeight,
           SurfaceClass::Other);
    addBox(scene, wall, gap_start, gap_end, face, back, kDoorHeight, f.height_m, SurfaceClass::Building);
  }
}

/// A wall with recessed doors and full-height niches about every feature_spacing_m.
void addCorridorWall(Scene& scene, DeterministicRng& rng, const WallFeatures& f, const WallLayout& wall)
{
  double wall_start = wall.u_start;
  double center = wall.first_center;
  while (true)
  {
    const bool niche = rng.uniform01() < f.niche_probability;
    const double width = niche ? kNicheWidth : f.door_width_m;
    const double gap_start = center - 0.5 * width;
    const double gap_end = center + 0.5 * width;
    if (gap_end > wall.u_end - f.door_width_m)
    {
      break;
    }
    addWallStretch(scene, rng, f, wall, wall_start, gap_start);
    addOpening(scene, f, wall, niche, gap_start, gap_end);
    wall_start = gap_end;
    center += f.feature_spacing_m + rng.uniform(-1.0, 1.0) * f.spacing_jitter_m;
  }
  addWallStretch(scene, rng, f, wall, wall_start, wall.u_end);
}

/// A wall with openings centered on the given u (ascending); openings that do not fit are skipped.
void addWallWithOpenings(Scene& scene, DeterministicRng& rng, const WallFeatures& f, const WallLayout& wall,
                         const std::vector<double>& centers)
{
  double wall_start = wall.u_start;
  for (const double center : centers)
  {
    const bool niche = rng.uniform01() < f.niche_probability;
    const double width = niche ? kNicheWidth : f.door_width_m;
    const double gap_start = center - 0.5 * width;
    const double gap_end = center + 0.5 * width;
    if (gap_start < wall_start + kDoorBackThickness || gap_end > wall.u_end - kDoorBackThickness)
    {
      continue;
    }
    addWallStretch(scene, rng, f, wall, wall_start, gap_start);
    addOpening(scene, f, wall, niche, gap_start, gap_end);
    wall_start = gap_end;
  }
  addWallStretch(scene, rng, f, wall, wall_start, wall.u_end);
}
}  // namespace

Scene urbanStreetWithHill(unsigned seed, double length_m, const GroundProfile& profile)
{
  UrbanStreetOptions options;
  options.length_m = length_m;
  return urbanStreetWithHill(seed, options, profile);
}

Scene urbanStreetWithHill(unsigned seed, const UrbanStreetOptions& options, const GroundProfile& profile)
{
  const Scene flat = Scene::urbanStreet(seed, options);
  std::vector<Primitive> primitives;
  primitives.reserve(flat.size() + 2 * kChordsPerVerticalCurve + 3);
  for (const Primitive& primitive : flat.primitives())
  {
    const auto* patch = std::get_if<PlanePatch>(&primitive.shape);
    if (patch != nullptr && primitive.surface_class == SurfaceClass::Ground)
    {
      const Aabb box = patch->bounds();
      for (const PlanePatch& piece :
           profilePatches(profile, patch->heightAt(0.0, 0.0), box.min.x(), box.max.x(), box.min.y(), box.max.y()))
      {
        primitives.emplace_back(piece, primitive.surface_class, primitive.reflectivity);
      }
      continue;
    }
    // Lowest ground under the footprint: the profile is monotonic, so one of the two x ends.
    const Aabb box = shapeBounds(primitive.shape);
    const double dz = std::min(profile.heightAt(box.min.x()), profile.heightAt(box.max.x()));
    primitives.emplace_back(lifted(primitive.shape, dz), primitive.surface_class, primitive.reflectivity);
  }
  return Scene(std::move(primitives));
}

Scene corridorScene(unsigned seed, const CorridorOptions& o)
{
  if (o.length_m <= 0.0 || o.width_m <= 0.0 || o.height_m <= kDoorHeight || o.feature_spacing_m <= o.door_width_m)
  {
    throw std::invalid_argument("corridorScene: invalid dimensions");
  }
  DeterministicRng rng(seed);
  Scene scene;
  const double half_width = 0.5 * o.width_m;
  const double outer = half_width + o.wall_thickness_m + kNicheDepth;
  const double x_lo = -o.wall_thickness_m - kCorridorFloorMargin;
  const double x_hi = o.length_m + o.wall_thickness_m + kCorridorFloorMargin;
  scene.add(PlanePatch::horizontal(0.0, x_lo, x_hi, -outer - kCorridorFloorMargin, outer + kCorridorFloorMargin),
            SurfaceClass::Ground);
  scene.add(PlanePatch::horizontal(o.height_m, x_lo, x_hi, -outer - kCorridorFloorMargin, outer + kCorridorFloorMargin),
            SurfaceClass::Building);
  // End walls.
  if (o.back_wall)
  {
    scene.add(boxFromCorners(-o.wall_thickness_m, 0.0, -outer, outer, 0.0, o.height_m), SurfaceClass::Building);
  }
  if (o.front_wall)
  {
    scene.add(boxFromCorners(o.length_m, o.length_m + o.wall_thickness_m, -outer, outer, 0.0, o.height_m),
              SurfaceClass::Building);
  }

  WallFeatures features;
  features.height_m = o.height_m;
  features.wall_thickness_m = o.wall_thickness_m;
  features.feature_spacing_m = o.feature_spacing_m;
  features.spacing_jitter_m = o.spacing_jitter_m;
  features.door_width_m = o.door_width_m;
  features.recess_depth_m = o.recess_depth_m;
  features.niche_probability = o.niche_probability;
  for (const double side : { 1.0, -1.0 })
  {
    if (!o.feature_x.empty())
    {
      WallLayout wall;
      wall.face_v = side * half_width;
      wall.outward = side;
      wall.u_start = 0.0;
      wall.u_end = o.length_m;
      std::vector<double> centers;
      for (std::size_t i = side > 0.0 ? 0 : 1; i < o.feature_x.size(); i += 2)
      {
        centers.push_back(o.feature_x[i]);
      }
      std::sort(centers.begin(), centers.end());
      addWallWithOpenings(scene, rng, features, wall, centers);
      continue;
    }
    WallLayout wall;
    wall.face_v = side * half_width;
    wall.outward = side;
    wall.u_start = 0.0;
    wall.u_end = o.length_m;
    // The two walls are offset by half a spacing so that features alternate sides.
    wall.first_center = (side > 0.0 ? 0.5 : 1.0) * o.feature_spacing_m + rng.uniform(-1.0, 1.0) * o.spacing_jitter_m;
    addCorridorWall(scene, rng, features, wall);
  }
  // Ceiling lights.
  for (double x = 0.5 * o.light_spacing_m; o.light_spacing_m > 0.0 && x < o.length_m; x += o.light_spacing_m)
  {
    scene.add(OrientedBox(Eigen::Vector3d(x, 0.0, o.height_m - kLightHalfExtentZ),
                          Eigen::Vector3d(kLightHalfExtentX, kLightHalfExtentY, kLightHalfExtentZ)),
              SurfaceClass::Other);
  }
  return scene;
}

Scene officeScene(unsigned seed, const OfficeOptions& o)
{
  if (o.first_length_m <= 2.0 * o.width_m || o.second_length_m <= o.width_m ||
      o.width_m <= 2.0 * o.clutter_depth_max_m || o.height_m <= kDoorHeight || o.feature_spacing_m <= o.door_width_m ||
      o.wall_thickness_m <= 0.0)
  {
    throw std::invalid_argument("officeScene: invalid dimensions");
  }
  DeterministicRng rng(seed);
  Scene scene;
  const double half_width = 0.5 * o.width_m;
  const double t = o.wall_thickness_m;
  const double outer = t + kNicheDepth + kCorridorFloorMargin;  // floor and ceiling beyond the wall faces
  const double inner_x = o.first_length_m - o.width_m;          // west face of the second corridor
  const double end_y = o.secondEndY();
  const double x_lo = -t - kCorridorFloorMargin;
  const double x_hi = o.first_length_m + outer;
  const double y_lo = -half_width - outer;
  const double y_hi = end_y + t + kCorridorFloorMargin;
  scene.add(PlanePatch::horizontal(0.0, x_lo, x_hi, y_lo, y_hi), SurfaceClass::Ground);
  scene.add(PlanePatch::horizontal(o.height_m, x_lo, x_hi, y_lo, y_hi), SurfaceClass::Building);
  // End walls of the two corridors.
  scene.add(boxFromCorners(-t, 0.0, -half_width - t - kNicheDepth, half_width + t + kNicheDepth, 0.0, o.height_m),
            SurfaceClass::Building);
  scene.add(
      boxFromCorners(inner_x - t - kNicheDepth, o.first_length_m + t + kNicheDepth, end_y, end_y + t, 0.0, o.height_m),
      SurfaceClass::Building);

  WallFeatures features;
  features.height_m = o.height_m;
  features.wall_thickness_m = t;
  features.feature_spacing_m = o.feature_spacing_m;
  features.spacing_jitter_m = o.spacing_jitter_m;
  features.door_width_m = o.door_width_m;
  features.recess_depth_m = o.recess_depth_m;
  features.clutter_probability = o.clutter_probability;
  features.clutter_depth_max_m = o.clutter_depth_max_m;
  features.close_niches = true;
  const auto first_center = [&](double u_start, double fraction)
  { return u_start + fraction * o.feature_spacing_m + rng.uniform(-1.0, 1.0) * o.spacing_jitter_m; };

  // First corridor, right (y < 0) wall: runs on to the outer corner.
  WallLayout right;
  right.face_v = -half_width;
  right.outward = -1.0;
  right.u_start = 0.0;
  right.u_end = o.first_length_m + t;
  right.first_center = first_center(right.u_start, 1.0);
  addCorridorWall(scene, rng, features, right);
  // First corridor, left (y > 0) wall: stops at the inner corner.
  WallLayout left;
  left.face_v = half_width;
  left.outward = 1.0;
  left.u_start = 0.0;
  left.u_end = inner_x;
  left.first_center = first_center(left.u_start, 0.5);
  addCorridorWall(scene, rng, features, left);
  // Second corridor, outer (x = first_length_m) wall: closes the first corridor's far end too.
  WallLayout far;
  far.along_y = true;
  far.face_v = o.first_length_m;
  far.outward = 1.0;
  far.u_start = -half_width - t;
  far.u_end = end_y;
  far.first_center = first_center(far.u_start, 0.5);
  addCorridorWall(scene, rng, features, far);
  // Second corridor, inner wall: from the inner corner on.
  WallLayout near;
  near.along_y = true;
  near.face_v = inner_x;
  near.outward = -1.0;
  near.u_start = half_width;
  near.u_end = end_y;
  near.first_center = first_center(near.u_start, 1.0);
  addCorridorWall(scene, rng, features, near);

  // Ceiling lights on both centerlines.
  const Eigen::Vector3d light(kLightHalfExtentX, kLightHalfExtentY, kLightHalfExtentZ);
  for (double x = 0.5 * o.light_spacing_m; o.light_spacing_m > 0.0 && x < inner_x; x += o.light_spacing_m)
  {
    scene.add(OrientedBox(Eigen::Vector3d(x, 0.0, o.height_m - kLightHalfExtentZ), light), SurfaceClass::Other);
  }
  for (double y = 0.0; o.light_spacing_m > 0.0 && y < end_y - 0.5 * o.light_spacing_m; y += o.light_spacing_m)
  {
    scene.add(OrientedBox(Eigen::Vector3d(o.turnCenterX(), y, o.height_m - kLightHalfExtentZ),
                          Eigen::Vector3d(light.y(), light.x(), light.z())),
              SurfaceClass::Other);
  }
  return scene;
}

Scene tunnelScene(unsigned seed, const TunnelOptions& o)
{
  if (o.length_m <= 0.0 || o.back_length_m < 0.0 || o.width_m <= 2.0 * o.walkway_width_m || o.wall_height_m <= 0.0 ||
      o.arch_chords < 1 || o.lining_thickness_m <= o.niche_depth_m || o.niche_height_m >= o.wall_height_m ||
      o.feature_spacing_min_m <= o.niche_width_m || o.feature_spacing_max_m < o.feature_spacing_min_m)
  {
    throw std::invalid_argument("tunnelScene: invalid dimensions");
  }
  DeterministicRng rng(seed);
  Scene scene;
  const double half_width = 0.5 * o.width_m;
  const double x_lo = -o.back_length_m;
  const double x_hi = o.length_m + kTunnelEndMargin;
  const double outer = half_width + o.lining_thickness_m;
  scene.add(PlanePatch::horizontal(0.0, x_lo - 1.0, x_hi + 1.0, -outer - 1.0, outer + 1.0), SurfaceClass::Ground);
  for (const double x : { x_lo - 1.0, x_hi })
  {
    scene.add(boxFromCorners(x, x + 1.0, -outer, outer, 0.0, o.crownHeight() + 1.0), SurfaceClass::Building);
  }
  // Arch: chords of the quarter circles of radius half_width centered on the wall tops.
  for (int k = 0; k < o.arch_chords; ++k)
  {
    const double a0 = 0.5 * kPi * k / o.arch_chords;
    const double a1 = 0.5 * kPi * (k + 1) / o.arch_chords;
    const double y0 = half_width * std::cos(a0);
    const double y1 = k + 1 == o.arch_chords ? 0.0 : half_width * std::cos(a1);  // cos(pi / 2) is not 0
    const double z0 = o.wall_height_m + half_width * std::sin(a0);
    const double z1 = k + 1 == o.arch_chords ? o.crownHeight() : o.wall_height_m + half_width * std::sin(a1);
    const double slope = (z1 - z0) / (y1 - y0);
    const double offset = z0 - slope * y0;
    scene.add(PlanePatch(0.0, slope, offset, x_lo, x_hi, y1, y0), SurfaceClass::Building);
    scene.add(PlanePatch(0.0, -slope, offset, x_lo, x_hi, -y0, -y1), SurfaceClass::Building);
  }
  // Walkway and cable tray run the whole length (they constrain nothing along x).
  scene.add(boxFromCorners(x_lo, x_hi, half_width - o.walkway_width_m, half_width, 0.0, o.walkway_height_m),
            SurfaceClass::Other);
  scene.add(boxFromCorners(x_lo, x_hi, -half_width, -half_width + kCableTrayWidth, kCableTrayZ,
                           kCableTrayZ + kCableTrayHeight),
            SurfaceClass::Other);

  // Sparse features; niches cut the side walls.
  std::vector<std::pair<double, double>> niches[2];  // per side (0: +y, 1: -y), x intervals
  for (double x = x_lo + rng.uniform(o.feature_spacing_min_m, o.feature_spacing_max_m); x < o.length_m;
       x += rng.uniform(o.feature_spacing_min_m, o.feature_spacing_max_m))
  {
    const double kind = rng.uniform01();
    const int side_index = rng.bernoulli(0.5) ? 0 : 1;
    const double side = side_index == 0 ? 1.0 : -1.0;
    if (kind < kTunnelNicheShare)
    {
      const double x0 = x - 0.5 * o.niche_width_m;
      const double x1 = x + 0.5 * o.niche_width_m;
      niches[side_index].emplace_back(x0, x1);
      scene.add(boxFromCorners(x0, x1, side * (half_width + o.niche_depth_m), side * outer, 0.0, o.wall_height_m),
                SurfaceClass::Building);
      scene.add(boxFromCorners(x0, x1, side * half_width, side * outer, o.niche_height_m, o.wall_height_m),
                SurfaceClass::Building);
    }
    else if (kind < kTunnelNicheShare + kTunnelLightShare)
    {
      scene.add(OrientedBox(Eigen::Vector3d(x, side * (half_width - kTunnelLightHalfDepth), o.wall_height_m - 0.4),
                            Eigen::Vector3d(kTunnelLightHalfLength, kTunnelLightHalfDepth, kTunnelLightHalfHeight)),
                SurfaceClass::Other);
    }
    else
    {
      scene.add(VerticalCylinder(x, side * (half_width - kStandpipeRadius - 0.02), kStandpipeRadius, 0.0,
                                 o.wall_height_m - 0.2),
                SurfaceClass::Pole);
    }
  }
  for (int side_index = 0; side_index < 2; ++side_index)
  {
    const double side = side_index == 0 ? 1.0 : -1.0;
    double start = x_lo;
    for (const auto& [x0, x1] : niches[side_index])
    {
      scene.add(boxFromCorners(start, x0, side * half_width, side * outer, 0.0, o.wall_height_m),
                SurfaceClass::Building);
      start = x1;
    }
    scene.add(boxFromCorners(start, x_hi, side * half_width, side * outer, 0.0, o.wall_height_m),
              SurfaceClass::Building);
  }
  return scene;
}

GroundProfile stairsProfile(const StairsOptions& o)
{
  GroundProfile profile;
  profile.start_x = 0.0;
  profile.length_m = o.run();
  profile.grade = o.totalRise() / o.run();
  profile.blend_length_m = kStairsBlend;
  return profile;
}

Scene stairsScene(unsigned seed, const StairsOptions& o)
{
  if (o.risers < 2 || o.rise_m <= 0.0 || o.tread_m <= 0.0 || o.width_m <= 1.2 || o.bottom_landing_m < 1.0 ||
      o.top_landing_m < 2.0 || o.ceiling_height_m <= o.totalRise() + kDoorHeight || o.wall_thickness_m <= 0.0)
  {
    throw std::invalid_argument("stairsScene: invalid dimensions");
  }
  DeterministicRng rng(seed);
  Scene scene;
  const double half_width = 0.5 * o.width_m;
  const double t = o.wall_thickness_m;
  const double x_lo = -o.bottom_landing_m;
  const double x_hi = o.run() + o.top_landing_m;
  const double top = o.totalRise();
  scene.add(PlanePatch::horizontal(0.0, x_lo - t - 1.0, x_hi + t + 1.0, -half_width - t - 1.0, half_width + t + 1.0),
            SurfaceClass::Ground);
  scene.add(PlanePatch::horizontal(o.ceiling_height_m, x_lo - t - 1.0, x_hi + t + 1.0, -half_width - t - 1.0,
                                   half_width + t + 1.0),
            SurfaceClass::Building);
  // Steps (solid blocks) and the top landing.
  const auto floor_at = [&](double x)
  {
    if (x < 0.0)
    {
      return 0.0;
    }
    return std::min(top, (std::floor(x / o.tread_m) + 1.0) * o.rise_m);
  };
  for (int i = 0; i + 1 < o.risers; ++i)
  {
    scene.add(boxFromCorners(i * o.tread_m, (i + 1) * o.tread_m, -half_width, half_width, 0.0, (i + 1) * o.rise_m),
              SurfaceClass::Ground);
  }
  scene.add(boxFromCorners(o.run(), x_hi, -half_width, half_width, 0.0, top), SurfaceClass::Ground);
  // Side and end walls.
  for (const double side : { 1.0, -1.0 })
  {
    scene.add(boxFromCorners(x_lo - t, x_hi + t, side * half_width, side * (half_width + t), 0.0, o.ceiling_height_m),
              SurfaceClass::Building);
  }
  scene.add(boxFromCorners(x_lo - t, x_lo, -half_width, half_width, 0.0, o.ceiling_height_m), SurfaceClass::Building);
  scene.add(boxFromCorners(x_hi, x_hi + t, -half_width, half_width, 0.0, o.ceiling_height_m), SurfaceClass::Building);
  // A door leaf (standing proud of the wall) at each end.
  const double door_span = half_width - 0.5 * kStairsDoorWidth - 0.1;
  const double bottom_door = rng.uniform(-door_span, door_span);
  const double top_door = rng.uniform(-door_span, door_span);
  scene.add(boxFromCorners(x_lo, x_lo + kStairsDoorProud, bottom_door - 0.5 * kStairsDoorWidth,
                           bottom_door + 0.5 * kStairsDoorWidth, 0.0, kDoorHeight),
            SurfaceClass::Other);
  scene.add(boxFromCorners(x_hi - kStairsDoorProud, x_hi, top_door - 0.5 * kStairsDoorWidth,
                           top_door + 0.5 * kStairsDoorWidth, top, top + kDoorHeight),
            SurfaceClass::Other);
  // Wall lamps about 2.3 m above the local floor, jittered along both walls.
  for (const double side : { 1.0, -1.0 })
  {
    for (double x = x_lo + rng.uniform(0.5, 1.5); x < x_hi - 0.5; x += rng.uniform(2.0, 3.0))
    {
      scene.add(OrientedBox(Eigen::Vector3d(x, side * (half_width - kStairsLampHalfDepth), floor_at(x) + 2.3),
                            Eigen::Vector3d(0.15, kStairsLampHalfDepth, 0.1)),
                SurfaceClass::Other);
    }
  }
  // Stepped handrail on one wall, 0.9 m above each tread.
  const double rail_side = rng.bernoulli(0.5) ? 1.0 : -1.0;
  for (int i = 0; i + 1 < o.risers; ++i)
  {
    const double z = (i + 1) * o.rise_m + 0.9;
    scene.add(boxFromCorners(i * o.tread_m, (i + 1) * o.tread_m, rail_side * (half_width - 0.08),
                             rail_side * (half_width - 0.03), z - 0.03, z + 0.03),
              SurfaceClass::Other);
  }
  // A bin on the bottom landing, a cabinet on the top landing, a riser pipe in a corner.
  const double object_side = rng.bernoulli(0.5) ? 1.0 : -1.0;
  scene.add(VerticalCylinder(x_lo + rng.uniform(0.5, o.bottom_landing_m - 1.0), object_side * (half_width - 0.3), 0.25,
                             0.0, 0.7),
            SurfaceClass::Other);
  const double cabinet_x = o.run() + rng.uniform(1.5, o.top_landing_m - 1.0);
  scene.add(boxFromCorners(cabinet_x - 0.4, cabinet_x + 0.4, -object_side * half_width,
                           -object_side * (half_width - 0.45), top, top + 1.2),
            SurfaceClass::Other);
  scene.add(VerticalCylinder(x_hi - 0.2, object_side * (half_width - 0.15), 0.06, 0.0, o.ceiling_height_m),
            SurfaceClass::Pole);
  return scene;
}

Scene openFieldScene(unsigned seed, double length_m, int object_count)
{
  DeterministicRng rng(seed);
  Scene scene;
  scene.add(PlanePatch::horizontal(0.0, -kFieldGroundMargin, std::max(length_m, 0.0) + kFieldGroundMargin,
                                   -kFieldGroundMargin, kFieldGroundMargin),
            SurfaceClass::Ground);
  const double span = std::max(length_m - kFieldFirstObjectX, 1.0);
  for (int i = 0; i < object_count; ++i)
  {
    const double x = kFieldFirstObjectX + span * (i + rng.uniform(0.2, 0.8)) / object_count;
    const double side = rng.uniform01() < 0.5 ? -1.0 : 1.0;
    const double y = side * (kFieldMinLateral + rng.uniform01() * kFieldLateralSpan);
    switch (i % 3)
    {
      case 0:  // a shed
        scene.add(OrientedBox(Eigen::Vector3d(x, y, 1.25), Eigen::Vector3d(2.0, 1.5, 1.25), rng.uniform(0.0, 3.0)),
                  SurfaceClass::Building);
        break;
      case 1:  // a pole
        scene.add(VerticalCylinder(x, y, 0.15, 0.0, rng.uniform(4.0, 8.0)), SurfaceClass::Pole);
        break;
      default:  // a boulder
        scene.add(Sphere(Eigen::Vector3d(x, y, 0.3), rng.uniform(0.8, 1.5)), SurfaceClass::Other);
        break;
    }
  }
  return scene;
}

}  // namespace sim
}  // namespace aloam
