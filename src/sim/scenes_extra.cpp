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
constexpr double kNicheProbability = 0.3;     // a feature is a full-height niche instead of a door
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
constexpr int kFieldObjectCount = 5;

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
}  // namespace

Scene urbanStreetWithHill(unsigned seed, double length_m, const GroundProfile& profile)
{
  const Scene flat = Scene::urbanStreet(seed, length_m);
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
  scene.add(boxFromCorners(-o.wall_thickness_m, 0.0, -outer, outer, 0.0, o.height_m), SurfaceClass::Building);
  scene.add(boxFromCorners(o.length_m, o.length_m + o.wall_thickness_m, -outer, outer, 0.0, o.height_m),
            SurfaceClass::Building);

  for (const double side : { 1.0, -1.0 })
  {
    const double face = side * half_width;
    const double back = side * (half_width + o.wall_thickness_m);
    double wall_start = 0.0;
    // The two walls are offset by half a spacing so that features alternate sides.
    double center = (side > 0.0 ? 0.5 : 1.0) * o.feature_spacing_m + rng.uniform(-1.0, 1.0) * o.spacing_jitter_m;
    while (true)
    {
      const bool niche = rng.uniform01() < kNicheProbability;
      const double width = niche ? kNicheWidth : o.door_width_m;
      const double gap_start = center - 0.5 * width;
      const double gap_end = center + 0.5 * width;
      if (gap_end > o.length_m - o.door_width_m)
      {
        break;
      }
      scene.add(boxFromCorners(wall_start, gap_start, face, back, 0.0, o.height_m), SurfaceClass::Building);
      if (niche)
      {
        const double niche_back = side * (half_width + kNicheDepth);
        scene.add(
            boxFromCorners(gap_start, gap_end, niche_back, niche_back + side * o.wall_thickness_m, 0.0, o.height_m),
            SurfaceClass::Building);
      }
      else
      {
        const double door = side * (half_width + o.recess_depth_m);
        scene.add(boxFromCorners(gap_start, gap_end, door, door + side * kDoorBackThickness, 0.0, kDoorHeight),
                  SurfaceClass::Other);
        scene.add(boxFromCorners(gap_start, gap_end, face, back, kDoorHeight, o.height_m), SurfaceClass::Building);
      }
      wall_start = gap_end;
      center += o.feature_spacing_m + rng.uniform(-1.0, 1.0) * o.spacing_jitter_m;
    }
    scene.add(boxFromCorners(wall_start, o.length_m, face, back, 0.0, o.height_m), SurfaceClass::Building);
  }
  // Ceiling lights.
  for (double x = 0.5 * o.light_spacing_m; x < o.length_m; x += o.light_spacing_m)
  {
    scene.add(OrientedBox(Eigen::Vector3d(x, 0.0, o.height_m - kLightHalfExtentZ),
                          Eigen::Vector3d(kLightHalfExtentX, kLightHalfExtentY, kLightHalfExtentZ)),
              SurfaceClass::Other);
  }
  return scene;
}

Scene openFieldScene(unsigned seed, double length_m)
{
  DeterministicRng rng(seed);
  Scene scene;
  scene.add(PlanePatch::horizontal(0.0, -kFieldGroundMargin, std::max(length_m, 0.0) + kFieldGroundMargin,
                                   -kFieldGroundMargin, kFieldGroundMargin),
            SurfaceClass::Ground);
  const double span = std::max(length_m - kFieldFirstObjectX, 1.0);
  for (int i = 0; i < kFieldObjectCount; ++i)
  {
    const double x = kFieldFirstObjectX + span * (i + rng.uniform(0.2, 0.8)) / kFieldObjectCount;
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
