#include "aloam_nodelet/sim/scene.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <utility>

#include "deterministic_rng.h"

namespace aloam
{
namespace sim
{
namespace
{
constexpr double kInf = std::numeric_limits<double>::infinity();
// Stand-in for a zero direction component when inverting it (1 / kTinyDirection stays finite).
constexpr double kTinyDirection = 1e-300;
// Primitives whose footprint covers more grid cells than this go to the always-tested list.
constexpr long kMaxCellsPerPrimitive = 256;
// Cells added around the gridded primitives when the grid is (re)built.
constexpr int kGridPaddingCells = 1;
// When the grid must grow, it grows by this fraction of its size on each side (amortized cost).
constexpr double kGridGrowthFraction = 0.5;

// simpleBox() layout.
constexpr double kSimpleGroundHalfExtent = 200.0;
constexpr double kSimpleBoxCenterX = 10.0;
constexpr double kSimpleBoxHalfX = 2.0;
constexpr double kSimpleBoxHalfY = 3.0;
constexpr double kSimpleBoxHeight = 3.0;

// urbanStreet() details not worth an option.
constexpr double kSidewalkBackExtra = 1.0;   // sidewalk runs this far under the buildings
constexpr double kMinBuildingLength = 3.0;   // shorter leftovers at the street ends are skipped
constexpr double kFacadeStepSplitMin = 0.3;  // split position of a stepped facade, fraction of length
constexpr double kFacadeStepSplitMax = 0.7;
constexpr double kReflectivityJitter = 0.1;  // per-primitive variation around the class default
constexpr double kMinReflectivity = 0.05;
constexpr double kCarLengthMin = 4.0;
constexpr double kCarLengthMax = 4.9;
constexpr double kCarWidthMin = 1.7;
constexpr double kCarWidthMax = 1.95;
constexpr double kCarClearance = 0.25;  // underbody height above ground
constexpr double kCarBodyHeightMin = 0.7;
constexpr double kCarBodyHeightMax = 0.95;
constexpr double kCarCabinHeightMin = 0.45;
constexpr double kCarCabinHeightMax = 0.65;
constexpr double kCarCabinLengthFraction = 0.55;
constexpr double kCarCabinRearShift = 0.08;  // cabin offset towards the rear, fraction of length
constexpr double kCarCabinWidthFraction = 0.9;
constexpr double kCarCurbGap = 0.3;             // between the curb and the car side
constexpr double kCarSlotJitter = 0.5;          // longitudinal placement noise within a slot
constexpr double kCarYawJitter = 0.05;          // rad
constexpr double kPoleCurbOffset = 0.5;         // poles stand this far behind the curb
constexpr double kTreeCurbOffset = 1.8;         // trees stand this far behind the curb
constexpr double kCrownCenterAboveTrunk = 0.7;  // crown center above the trunk top, fraction of radius

double jitteredReflectivity(SurfaceClass surface_class, DeterministicRng& rng)
{
  const double r = defaultReflectivity(surface_class) + rng.uniform(-kReflectivityJitter, kReflectivityJitter);
  return std::clamp(r, kMinReflectivity, 1.0);
}

bool isFinite(const Aabb& box)
{
  return box.min.allFinite() && box.max.allFinite();
}
// A ray that can be cast: finite origin, finite non-zero direction, positive range.
bool castable(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction, double max_range)
{
  return max_range > kMinHitDistance && origin.allFinite() && direction.allFinite() && direction.squaredNorm() > 0.0;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Ray, Aabb

Ray::Ray(const Eigen::Vector3d& origin_in, const Eigen::Vector3d& direction_in)
  : origin(origin_in), direction(direction_in.normalized())
{
  // A zero component gets a huge finite inverse: slab tests then need no special case.
  for (int a = 0; a < 3; ++a)
  {
    const double d = direction[a] == 0.0 ? std::copysign(kTinyDirection, direction[a]) : direction[a];
    inv_direction[a] = 1.0 / d;
  }
}

void Aabb::extend(const Eigen::Vector3d& p)
{
  min = min.cwiseMin(p);
  max = max.cwiseMax(p);
}

void Aabb::extend(const Aabb& other)
{
  min = min.cwiseMin(other.min);
  max = max.cwiseMax(other.max);
}

bool Aabb::clip(const Ray& ray, double t_min, double t_max, double* t_enter, double* t_exit) const
{
  // Branch-free slab test; inv_direction is finite (see Ray), so no 0 * inf appears.
  const Eigen::Array3d t0 = (min - ray.origin).array() * ray.inv_direction.array();
  const Eigen::Array3d t1 = (max - ray.origin).array() * ray.inv_direction.array();
  const double lo = std::max(t_min, t0.min(t1).maxCoeff());
  const double hi = std::min(t_max, t0.max(t1).minCoeff());
  *t_enter = lo;
  *t_exit = hi;
  return lo <= hi;
}

// ---------------------------------------------------------------------------------------------
// PlanePatch

PlanePatch::PlanePatch(double slope_x, double slope_y, double offset_z, double x_min, double x_max, double y_min,
                       double y_max)
  : slope_x_(slope_x)
  , slope_y_(slope_y)
  , offset_z_(offset_z)
  , x_min_(x_min)
  , x_max_(x_max)
  , y_min_(y_min)
  , y_max_(y_max)
  , normal_(Eigen::Vector3d(-slope_x, -slope_y, 1.0).normalized())
{
  const bool finite = std::isfinite(slope_x) && std::isfinite(slope_y) && std::isfinite(offset_z) &&
                      std::isfinite(x_min) && std::isfinite(x_max) && std::isfinite(y_min) && std::isfinite(y_max);
  if (!finite || !(x_min < x_max) || !(y_min < y_max))
  {
    throw std::invalid_argument("PlanePatch needs finite parameters and a non-empty rectangle");
  }
}

PlanePatch PlanePatch::horizontal(double z, double x_min, double x_max, double y_min, double y_max)
{
  return PlanePatch(0.0, 0.0, z, x_min, x_max, y_min, y_max);
}

bool PlanePatch::intersect(const Ray& ray, double t_min, double t_max, ShapeHit* hit) const
{
  // f(p) = slope_x * x + slope_y * y - z + offset_z vanishes on the plane.
  const Eigen::Vector3d& o = ray.origin;
  const Eigen::Vector3d& d = ray.direction;
  const double denom = slope_x_ * d.x() + slope_y_ * d.y() - d.z();
  if (denom == 0.0)
  {
    return false;
  }
  const double t = -(slope_x_ * o.x() + slope_y_ * o.y() - o.z() + offset_z_) / denom;
  if (!(t > t_min && t < t_max))
  {
    return false;
  }
  const double x = o.x() + t * d.x();
  const double y = o.y() + t * d.y();
  if (x < x_min_ || x > x_max_ || y < y_min_ || y > y_max_)
  {
    return false;
  }
  hit->distance = t;
  hit->normal = normal_;
  return true;
}

Aabb PlanePatch::bounds() const
{
  Aabb box;
  for (const double x : { x_min_, x_max_ })
  {
    for (const double y : { y_min_, y_max_ })
    {
      box.extend(Eigen::Vector3d(x, y, heightAt(x, y)));
    }
  }
  return box;
}

// ---------------------------------------------------------------------------------------------
// OrientedBox

OrientedBox::OrientedBox(const Eigen::Vector3d& center, const Eigen::Vector3d& half_extents, double yaw)
  : center_(center), half_extents_(half_extents), yaw_(yaw), cos_yaw_(std::cos(yaw)), sin_yaw_(std::sin(yaw))
{
  if (!center.allFinite() || !half_extents.allFinite() || !(half_extents.array() > 0.0).all() || !std::isfinite(yaw))
  {
    throw std::invalid_argument("OrientedBox needs a finite center and yaw and positive half extents");
  }
}

bool OrientedBox::intersect(const Ray& ray, double t_min, double t_max, ShapeHit* hit) const
{
  // Ray in the box frame (rotated by -yaw about the center).
  const Eigen::Vector3d rel = ray.origin - center_;
  const Eigen::Vector3d& d = ray.direction;
  const double lo[3] = { cos_yaw_ * rel.x() + sin_yaw_ * rel.y(), -sin_yaw_ * rel.x() + cos_yaw_ * rel.y(), rel.z() };
  const double ld[3] = { cos_yaw_ * d.x() + sin_yaw_ * d.y(), -sin_yaw_ * d.x() + cos_yaw_ * d.y(), d.z() };

  double t_enter = -kInf;
  double t_exit = kInf;
  int enter_axis = 0;
  int exit_axis = 0;
  double enter_sign = 1.0;  // sign of the local normal of the entry face
  double exit_sign = 1.0;
  for (int a = 0; a < 3; ++a)
  {
    const double h = half_extents_[a];
    if (ld[a] == 0.0)
    {
      if (lo[a] < -h || lo[a] > h)
      {
        return false;
      }
      continue;
    }
    const double inv = 1.0 / ld[a];
    const double t_near = (ld[a] > 0.0 ? -h - lo[a] : h - lo[a]) * inv;
    const double t_far = (ld[a] > 0.0 ? h - lo[a] : -h - lo[a]) * inv;
    if (t_near > t_enter)
    {
      t_enter = t_near;
      enter_axis = a;
      enter_sign = ld[a] > 0.0 ? -1.0 : 1.0;
    }
    if (t_far < t_exit)
    {
      t_exit = t_far;
      exit_axis = a;
      exit_sign = ld[a] > 0.0 ? 1.0 : -1.0;
    }
    if (t_enter > t_exit)
    {
      return false;
    }
  }

  int axis = 0;
  double sign = 1.0;
  if (t_enter > t_min && t_enter < t_max)
  {
    hit->distance = t_enter;
    axis = enter_axis;
    sign = enter_sign;
  }
  else if (t_exit > t_min && t_exit < t_max)
  {
    // Origin inside the box: the exit face is the visible one.
    hit->distance = t_exit;
    axis = exit_axis;
    sign = exit_sign;
  }
  else
  {
    return false;
  }
  Eigen::Vector3d local_normal = Eigen::Vector3d::Zero();
  local_normal[axis] = sign;
  hit->normal = Eigen::Vector3d(cos_yaw_ * local_normal.x() - sin_yaw_ * local_normal.y(),
                                sin_yaw_ * local_normal.x() + cos_yaw_ * local_normal.y(), local_normal.z());
  return true;
}

Aabb OrientedBox::bounds() const
{
  const double ex = std::abs(cos_yaw_) * half_extents_.x() + std::abs(sin_yaw_) * half_extents_.y();
  const double ey = std::abs(sin_yaw_) * half_extents_.x() + std::abs(cos_yaw_) * half_extents_.y();
  const Eigen::Vector3d e(ex, ey, half_extents_.z());
  Aabb box;
  box.min = center_ - e;
  box.max = center_ + e;
  return box;
}

// ---------------------------------------------------------------------------------------------
// VerticalCylinder

VerticalCylinder::VerticalCylinder(double center_x, double center_y, double radius, double z_min, double z_max)
  : center_x_(center_x), center_y_(center_y), radius_(radius), z_min_(z_min), z_max_(z_max)
{
  if (!std::isfinite(center_x) || !std::isfinite(center_y) || !std::isfinite(radius) || !std::isfinite(z_min) ||
      !std::isfinite(z_max) || !(radius > 0.0) || !(z_max > z_min))
  {
    throw std::invalid_argument("VerticalCylinder needs a positive radius and z_max > z_min");
  }
}

bool VerticalCylinder::intersect(const Ray& ray, double t_min, double t_max, ShapeHit* hit) const
{
  const double ox = ray.origin.x() - center_x_;
  const double oy = ray.origin.y() - center_y_;
  const double oz = ray.origin.z();
  const Eigen::Vector3d& d = ray.direction;
  const double r2 = radius_ * radius_;
  double best = t_max;
  bool found = false;

  // Mantle: |(o + t d)_xy|^2 = r^2, i.e. a t^2 + 2 b t + c = 0.
  const double a = d.x() * d.x() + d.y() * d.y();
  if (a > 0.0)
  {
    const double b = ox * d.x() + oy * d.y();
    const double c = ox * ox + oy * oy - r2;
    const double disc = b * b - a * c;
    if (disc >= 0.0)
    {
      const double sq = std::sqrt(disc);
      for (const double t : { (-b - sq) / a, (-b + sq) / a })
      {
        if (t > t_min && t < best)
        {
          const double z = oz + t * d.z();
          if (z >= z_min_ && z <= z_max_)
          {
            best = t;
            hit->normal = Eigen::Vector3d((ox + t * d.x()) / radius_, (oy + t * d.y()) / radius_, 0.0);
            found = true;
            break;
          }
        }
      }
    }
  }
  // Caps.
  if (d.z() != 0.0)
  {
    for (const double zc : { z_min_, z_max_ })
    {
      const double t = (zc - oz) / d.z();
      if (t > t_min && t < best)
      {
        const double x = ox + t * d.x();
        const double y = oy + t * d.y();
        if (x * x + y * y <= r2)
        {
          best = t;
          hit->normal = Eigen::Vector3d(0.0, 0.0, zc == z_max_ ? 1.0 : -1.0);
          found = true;
        }
      }
    }
  }
  if (found)
  {
    hit->distance = best;
  }
  return found;
}

Aabb VerticalCylinder::bounds() const
{
  Aabb box;
  box.min = Eigen::Vector3d(center_x_ - radius_, center_y_ - radius_, z_min_);
  box.max = Eigen::Vector3d(center_x_ + radius_, center_y_ + radius_, z_max_);
  return box;
}

// ---------------------------------------------------------------------------------------------
// Sphere

Sphere::Sphere(const Eigen::Vector3d& center, double radius) : center_(center), radius_(radius)
{
  if (!center.allFinite() || !std::isfinite(radius) || !(radius > 0.0))
  {
    throw std::invalid_argument("Sphere needs a finite center and a positive radius");
  }
}

bool Sphere::intersect(const Ray& ray, double t_min, double t_max, ShapeHit* hit) const
{
  const Eigen::Vector3d oc = ray.origin - center_;
  const double b = oc.dot(ray.direction);
  const double c = oc.squaredNorm() - radius_ * radius_;
  const double disc = b * b - c;
  if (disc < 0.0)
  {
    return false;
  }
  const double sq = std::sqrt(disc);
  double t = -b - sq;
  if (!(t > t_min))
  {
    t = -b + sq;
  }
  if (!(t > t_min && t < t_max))
  {
    return false;
  }
  hit->distance = t;
  hit->normal = (oc + t * ray.direction) / radius_;
  return true;
}

Aabb Sphere::bounds() const
{
  Aabb box;
  box.min = center_.array() - radius_;
  box.max = center_.array() + radius_;
  return box;
}

// ---------------------------------------------------------------------------------------------
// Shape helpers, Primitive

double defaultReflectivity(SurfaceClass surface_class)
{
  switch (surface_class)
  {
    case SurfaceClass::Ground:
      return 0.2;
    case SurfaceClass::Building:
      return 0.45;
    case SurfaceClass::Vehicle:
      return 0.7;
    case SurfaceClass::Pole:
      return 0.6;
    case SurfaceClass::TreeTrunk:
      return 0.3;
    case SurfaceClass::TreeCrown:
      return 0.25;
    case SurfaceClass::Other:
      break;
  }
  return 0.5;
}

Primitive::Primitive(Shape shape_in, SurfaceClass surface_class_in)
  : Primitive(std::move(shape_in), surface_class_in, defaultReflectivity(surface_class_in))
{
}

Primitive::Primitive(Shape shape_in, SurfaceClass surface_class_in, double reflectivity_in)
  : shape(std::move(shape_in)), surface_class(surface_class_in), reflectivity(std::clamp(reflectivity_in, 0.0, 1.0))
{
}

bool intersectShape(const Shape& shape, const Ray& ray, double t_min, double t_max, ShapeHit* hit)
{
  return std::visit([&](const auto& s) { return s.intersect(ray, t_min, t_max, hit); }, shape);
}

Aabb shapeBounds(const Shape& shape)
{
  return std::visit([](const auto& s) { return s.bounds(); }, shape);
}

// ---------------------------------------------------------------------------------------------
// Scene

Scene::Scene(double cell_size_m) : cell_size_(cell_size_m)
{
  if (!(cell_size_m > 0.0) || !std::isfinite(cell_size_m))
  {
    throw std::invalid_argument("Scene cell size must be positive");
  }
}

Scene::Scene(std::vector<Primitive> primitives, double cell_size_m) : Scene(cell_size_m)
{
  // Size the grid once for all primitives, then insert them.
  Aabb extent;
  for (const Primitive& p : primitives)
  {
    const Aabb b = shapeBounds(p.shape);
    if (!isLarge(b))
    {
      extent.extend(b);
    }
  }
  if (!extent.empty())
  {
    rebuildGrid(extent);
  }
  primitives_.reserve(primitives.size());
  primitive_bounds_.reserve(primitives.size());
  for (Primitive& p : primitives)
  {
    add(std::move(p));
  }
}

int Scene::add(Shape shape, SurfaceClass surface_class)
{
  return add(Primitive(std::move(shape), surface_class));
}

int Scene::add(Primitive primitive)
{
  const int id = static_cast<int>(primitives_.size());
  const Aabb b = shapeBounds(primitive.shape);
  primitives_.push_back(std::move(primitive));
  primitive_bounds_.push_back(b);
  bounds_.extend(b);
  if (isLarge(b))
  {
    large_ids_.push_back(id);
    return id;
  }
  gridded_ids_.push_back(id);
  gridded_bounds_.extend(b);

  const bool inside = grid_nx_ > 0 && b.min.x() >= grid_x0_ && b.min.y() >= grid_y0_ &&
                      b.max.x() <= grid_x0_ + grid_nx_ * cell_size_ && b.max.y() <= grid_y0_ + grid_ny_ * cell_size_;
  if (inside)
  {
    insertIntoGrid(id);
    return id;
  }
  // Grow the grid with slack so that a sequence of additions costs amortized O(1) rebuilds.
  Aabb extent = gridded_bounds_;
  const Eigen::Vector3d slack = kGridGrowthFraction * (extent.max - extent.min);
  extent.min.head<2>() -= slack.head<2>();
  extent.max.head<2>() += slack.head<2>();
  rebuildGrid(extent);
  return id;
}

int Scene::countClass(SurfaceClass surface_class) const
{
  return static_cast<int>(std::count_if(primitives_.begin(), primitives_.end(),
                                        [&](const Primitive& p) { return p.surface_class == surface_class; }));
}

bool Scene::isLarge(const Aabb& box) const
{
  if (!isFinite(box))
  {
    return true;
  }
  const double nx = std::ceil((box.max.x() - box.min.x()) / cell_size_) + 1.0;
  const double ny = std::ceil((box.max.y() - box.min.y()) / cell_size_) + 1.0;
  return nx * ny > static_cast<double>(kMaxCellsPerPrimitive);
}

void Scene::rebuildGrid(const Aabb& extent)
{
  grid_x0_ = extent.min.x() - kGridPaddingCells * cell_size_;
  grid_y0_ = extent.min.y() - kGridPaddingCells * cell_size_;
  grid_nx_ = static_cast<int>(std::ceil((extent.max.x() - extent.min.x()) / cell_size_)) + 2 * kGridPaddingCells;
  grid_ny_ = static_cast<int>(std::ceil((extent.max.y() - extent.min.y()) / cell_size_)) + 2 * kGridPaddingCells;
  cells_.assign(static_cast<std::size_t>(grid_nx_) * static_cast<std::size_t>(grid_ny_), {});
  for (const int id : gridded_ids_)
  {
    insertIntoGrid(id);
  }
}

void Scene::cellRange(const Aabb& box, int* ix0, int* iy0, int* ix1, int* iy1) const
{
  const auto cell = [this](double v, double v0, int n)
  { return std::clamp(static_cast<int>(std::floor((v - v0) / cell_size_)), 0, n - 1); };
  *ix0 = cell(box.min.x(), grid_x0_, grid_nx_);
  *ix1 = cell(box.max.x(), grid_x0_, grid_nx_);
  *iy0 = cell(box.min.y(), grid_y0_, grid_ny_);
  *iy1 = cell(box.max.y(), grid_y0_, grid_ny_);
}

void Scene::insertIntoGrid(int id)
{
  int ix0 = 0;
  int iy0 = 0;
  int ix1 = 0;
  int iy1 = 0;
  cellRange(primitive_bounds_[static_cast<std::size_t>(id)], &ix0, &iy0, &ix1, &iy1);
  for (int iy = iy0; iy <= iy1; ++iy)
  {
    for (int ix = ix0; ix <= ix1; ++ix)
    {
      cells_[static_cast<std::size_t>(iy) * static_cast<std::size_t>(grid_nx_) + static_cast<std::size_t>(ix)]
          .push_back(id);
    }
  }
}

void Scene::testPrimitive(int id, const Ray& ray, double* best_t, ShapeHit* best_hit, int* best_id) const
{
  const std::size_t i = static_cast<std::size_t>(id);
  double t_enter = 0.0;
  double t_exit = 0.0;
  if (!primitive_bounds_[i].clip(ray, kMinHitDistance, *best_t, &t_enter, &t_exit))
  {
    return;
  }
  ShapeHit hit;
  if (intersectShape(primitives_[i].shape, ray, kMinHitDistance, *best_t, &hit))
  {
    *best_t = hit.distance;
    *best_hit = hit;
    *best_id = id;
  }
}

std::optional<Hit> Scene::makeHit(const Ray& ray, double t, const ShapeHit& shape_hit, int id) const
{
  if (id < 0)
  {
    return std::nullopt;
  }
  Hit hit;
  hit.distance = t;
  hit.point = ray.at(t);
  hit.normal = shape_hit.normal.dot(ray.direction) > 0.0 ? -shape_hit.normal : shape_hit.normal;
  hit.surface_id = id;
  hit.surface_class = primitives_[static_cast<std::size_t>(id)].surface_class;
  return hit;
}

std::optional<Hit> Scene::intersect(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                                    double max_range) const
{
  if (!castable(origin, direction, max_range))
  {
    return std::nullopt;
  }
  const Ray ray(origin, direction);
  // Hits must be strictly closer than best_t; allow a hit exactly at max_range.
  double best_t = std::nextafter(max_range, kInf);
  ShapeHit best_hit;
  int best_id = -1;

  // Large primitives (ground) first: an early close hit shortens the grid walk.
  for (const int id : large_ids_)
  {
    testPrimitive(id, ray, &best_t, &best_hit, &best_id);
  }

  double t0 = 0.0;
  double t1 = 0.0;
  if (grid_nx_ == 0 || !gridded_bounds_.clip(ray, kMinHitDistance, best_t, &t0, &t1))
  {
    return makeHit(ray, best_t, best_hit, best_id);
  }

  // 2D DDA over the xy grid from the entry point into the gridded bounds.
  const Eigen::Vector3d entry = ray.at(t0);
  const double dx = ray.direction.x();
  const double dy = ray.direction.y();
  int ix = std::clamp(static_cast<int>(std::floor((entry.x() - grid_x0_) / cell_size_)), 0, grid_nx_ - 1);
  int iy = std::clamp(static_cast<int>(std::floor((entry.y() - grid_y0_) / cell_size_)), 0, grid_ny_ - 1);
  const int step_x = dx > 0.0 ? 1 : (dx < 0.0 ? -1 : 0);
  const int step_y = dy > 0.0 ? 1 : (dy < 0.0 ? -1 : 0);
  // Ray parameter at which the next cell boundary in x (y) is crossed, and the spacing of those.
  double t_next_x = kInf;
  double t_next_y = kInf;
  const double t_delta_x = step_x != 0 ? cell_size_ / std::abs(dx) : kInf;
  const double t_delta_y = step_y != 0 ? cell_size_ / std::abs(dy) : kInf;
  if (step_x != 0)
  {
    const double boundary = grid_x0_ + (ix + (step_x > 0 ? 1 : 0)) * cell_size_;
    t_next_x = (boundary - ray.origin.x()) / dx;
  }
  if (step_y != 0)
  {
    const double boundary = grid_y0_ + (iy + (step_y > 0 ? 1 : 0)) * cell_size_;
    t_next_y = (boundary - ray.origin.y()) / dy;
  }

  while (true)
  {
    const std::vector<int>& cell =
        cells_[static_cast<std::size_t>(iy) * static_cast<std::size_t>(grid_nx_) + static_cast<std::size_t>(ix)];
    for (const int id : cell)
    {
      testPrimitive(id, ray, &best_t, &best_hit, &best_id);
    }
    const double t_cell_exit = std::min(t_next_x, t_next_y);
    // Done once the nearest hit lies inside the cells walked so far, or the ray leaves the bounds.
    if (best_t <= t_cell_exit || t_cell_exit >= std::min(t1, best_t))
    {
      break;
    }
    if (t_next_x < t_next_y)
    {
      ix += step_x;
      t_next_x += t_delta_x;
      if (ix < 0 || ix >= grid_nx_)
      {
        break;
      }
    }
    else
    {
      iy += step_y;
      t_next_y += t_delta_y;
      if (iy < 0 || iy >= grid_ny_)
      {
        break;
      }
    }
  }
  return makeHit(ray, best_t, best_hit, best_id);
}

std::optional<Hit> Scene::intersectBruteForce(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                                              double max_range) const
{
  if (!castable(origin, direction, max_range))
  {
    return std::nullopt;
  }
  const Ray ray(origin, direction);
  double best_t = std::nextafter(max_range, kInf);
  ShapeHit best_hit;
  int best_id = -1;
  for (std::size_t i = 0; i < primitives_.size(); ++i)
  {
    ShapeHit hit;
    if (intersectShape(primitives_[i].shape, ray, kMinHitDistance, best_t, &hit))
    {
      best_t = hit.distance;
      best_hit = hit;
      best_id = static_cast<int>(i);
    }
  }
  return makeHit(ray, best_t, best_hit, best_id);
}

// ---------------------------------------------------------------------------------------------
// Builders

Scene Scene::flatGround(double half_extent_m)
{
  std::vector<Primitive> primitives;
  primitives.emplace_back(PlanePatch::horizontal(0.0, -half_extent_m, half_extent_m, -half_extent_m, half_extent_m),
                          SurfaceClass::Ground);
  return Scene(std::move(primitives));
}

Scene Scene::simpleBox()
{
  std::vector<Primitive> primitives;
  primitives.emplace_back(PlanePatch::horizontal(0.0, -kSimpleGroundHalfExtent, kSimpleGroundHalfExtent,
                                                 -kSimpleGroundHalfExtent, kSimpleGroundHalfExtent),
                          SurfaceClass::Ground);
  primitives.emplace_back(OrientedBox(Eigen::Vector3d(kSimpleBoxCenterX, 0.0, 0.5 * kSimpleBoxHeight),
                                      Eigen::Vector3d(kSimpleBoxHalfX, kSimpleBoxHalfY, 0.5 * kSimpleBoxHeight)),
                          SurfaceClass::Building);
  return Scene(std::move(primitives));
}

Scene Scene::urbanStreet(unsigned seed, double length_m)
{
  UrbanStreetOptions options;
  options.length_m = length_m;
  return urbanStreet(seed, options);
}

Scene Scene::urbanStreet(unsigned seed, const UrbanStreetOptions& o)
{
  DeterministicRng rng(seed);
  std::vector<Primitive> primitives;
  const auto add = [&](Shape shape, SurfaceClass surface_class)
  {
    const double reflectivity = jitteredReflectivity(surface_class, rng);
    primitives.emplace_back(std::move(shape), surface_class, reflectivity);
  };
  const auto box = [](double cx, double cy, double cz, double hx, double hy, double hz, double yaw = 0.0)
  { return OrientedBox(Eigen::Vector3d(cx, cy, cz), Eigen::Vector3d(hx, hy, hz), yaw); };

  const double x_begin = -o.end_margin_m;
  const double x_end = o.length_m + o.end_margin_m;
  const double half_width = 0.5 * rng.uniform(o.street_width_min_m, o.street_width_max_m);

  // Ground.
  add(PlanePatch::horizontal(0.0, x_begin - o.ground_margin_m, x_end + o.ground_margin_m, -o.ground_margin_m,
                             o.ground_margin_m),
      SurfaceClass::Ground);

  for (const double side : { -1.0, 1.0 })
  {
    // Sidewalk slabs from the curb to under the buildings.
    const double sidewalk_outer = half_width + o.sidewalk_width_m + o.building_setback_max_m + kSidewalkBackExtra;
    const double sidewalk_half_y = 0.5 * (sidewalk_outer - half_width);
    for (double x = x_begin; x < x_end; x += o.sidewalk_segment_m)
    {
      const double len = std::min(o.sidewalk_segment_m, x_end - x);
      add(box(x + 0.5 * len, side * (half_width + sidewalk_half_y), 0.5 * o.curb_height_m, 0.5 * len, sidewalk_half_y,
              0.5 * o.curb_height_m),
          SurfaceClass::Ground);
    }

    // Buildings: blocks along the street, some with a stepped facade, with gaps (alleys) between.
    const double facade_line = half_width + o.sidewalk_width_m;
    const auto building = [&](double x0, double len, double setback, double depth, double height)
    {
      const double facade_y = facade_line + setback;
      add(box(x0 + 0.5 * len, side * (facade_y + 0.5 * depth), 0.5 * height, 0.5 * len, 0.5 * depth, 0.5 * height),
          SurfaceClass::Building);
    };
    for (double x = x_begin; x < x_end;)
    {
      const double len = std::min(rng.uniform(o.building_length_min_m, o.building_length_max_m), x_end - x);
      if (len < kMinBuildingLength)
      {
        break;
      }
      const double depth = rng.uniform(o.building_depth_min_m, o.building_depth_max_m);
      const double height = rng.uniform(o.building_height_min_m, o.building_height_max_m);
      const double setback = rng.uniform(0.0, o.building_setback_max_m);
      if (rng.bernoulli(o.facade_step_probability))
      {
        const double split = len * rng.uniform(kFacadeStepSplitMin, kFacadeStepSplitMax);
        const double setback2 = rng.uniform(0.0, o.building_setback_max_m);
        const double height2 = rng.uniform(o.building_height_min_m, o.building_height_max_m);
        building(x, split, setback, depth, height);
        building(x + split, len - split, setback2, depth, height2);
      }
      else
      {
        building(x, len, setback, depth, height);
      }
      x += len;
      if (rng.bernoulli(o.gap_probability))
      {
        x += rng.uniform(o.gap_min_m, o.gap_max_m);
      }
    }

    // Parked cars along the curb: a body box and a cabin box.
    for (double slot = x_begin; slot + o.car_slot_length_m <= x_end; slot += o.car_slot_length_m)
    {
      if (!rng.bernoulli(o.car_probability))
      {
        continue;
      }
      const double len = rng.uniform(kCarLengthMin, kCarLengthMax);
      const double width = rng.uniform(kCarWidthMin, kCarWidthMax);
      const double body_h = rng.uniform(kCarBodyHeightMin, kCarBodyHeightMax);
      const double cabin_h = rng.uniform(kCarCabinHeightMin, kCarCabinHeightMax);
      const double yaw = rng.uniform(-kCarYawJitter, kCarYawJitter);
      const double cx = slot + 0.5 * o.car_slot_length_m + rng.uniform(-kCarSlotJitter, kCarSlotJitter);
      const double cy = side * (half_width - kCarCurbGap - 0.5 * width);
      add(box(cx, cy, kCarClearance + 0.5 * body_h, 0.5 * len, 0.5 * width, 0.5 * body_h, yaw), SurfaceClass::Vehicle);
      const double shift = -kCarCabinRearShift * len;
      add(box(cx + shift * std::cos(yaw), cy + shift * std::sin(yaw), kCarClearance + body_h + 0.5 * cabin_h,
              0.5 * kCarCabinLengthFraction * len, 0.5 * kCarCabinWidthFraction * width, 0.5 * cabin_h, yaw),
          SurfaceClass::Vehicle);
    }

    // Poles behind the curb, and trees midway between some consecutive poles.
    double previous_pole_x = -kInf;
    for (double x = x_begin + rng.uniform(0.0, o.pole_spacing_max_m); x < x_end;
         x += rng.uniform(o.pole_spacing_min_m, o.pole_spacing_max_m))
    {
      const double radius = rng.uniform(o.pole_radius_min_m, o.pole_radius_max_m);
      const double height = rng.uniform(o.pole_height_min_m, o.pole_height_max_m);
      add(VerticalCylinder(x, side * (half_width + kPoleCurbOffset), radius, 0.0, height), SurfaceClass::Pole);
      if (std::isfinite(previous_pole_x) && rng.bernoulli(o.tree_probability))
      {
        const double tx = 0.5 * (previous_pole_x + x);
        const double ty = side * (half_width + kTreeCurbOffset);
        const double trunk_r = rng.uniform(o.trunk_radius_min_m, o.trunk_radius_max_m);
        const double trunk_h = rng.uniform(o.trunk_height_min_m, o.trunk_height_max_m);
        const double crown_r = rng.uniform(o.crown_radius_min_m, o.crown_radius_max_m);
        add(VerticalCylinder(tx, ty, trunk_r, 0.0, trunk_h), SurfaceClass::TreeTrunk);
        add(Sphere(Eigen::Vector3d(tx, ty, trunk_h + kCrownCenterAboveTrunk * crown_r), crown_r),
            SurfaceClass::TreeCrown);
      }
      previous_pole_x = x;
    }
  }
  return Scene(std::move(primitives));
}

}  // namespace sim
}  // namespace aloam
