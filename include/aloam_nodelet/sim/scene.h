// Synthetic 3D scene made of analytic primitives, with fast ray intersection (used by the lidar
// simulator and by the unit tests of the LOAM core).
#pragma once

#include <cstdint>
#include <limits>
#include <optional>
#include <variant>
#include <vector>

#include <Eigen/Core>

namespace aloam
{
namespace sim
{
/// Hits closer than this along a ray are ignored (avoids self-hits at the ray origin).
constexpr double kMinHitDistance = 1e-6;

/// A half-line origin + t * direction, t >= 0, with a unit direction.
struct Ray
{
  /// `direction` need not be unit length but must be non-zero; it is normalized here.
  Ray(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction);

  Eigen::Vector3d at(double t) const { return origin + t * direction; }

  Eigen::Vector3d origin;
  Eigen::Vector3d direction;      // unit length
  Eigen::Vector3d inv_direction;  // component-wise 1 / direction (huge but finite for zero components)
};

/// Axis-aligned bounding box; default-constructed it is empty.
struct Aabb
{
  Eigen::Vector3d min = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d max = Eigen::Vector3d::Constant(-std::numeric_limits<double>::infinity());

  bool empty() const { return (min.array() > max.array()).any(); }
  void extend(const Eigen::Vector3d& p);
  void extend(const Aabb& other);
  /// Slab test: the parameter interval [*t_enter, *t_exit] of the ray inside the box, clipped to
  /// [t_min, t_max]. False when that interval is empty.
  bool clip(const Ray& ray, double t_min, double t_max, double* t_enter, double* t_exit) const;
};

/// Result of a ray-vs-shape test.
struct ShapeHit
{
  double distance = 0.0;                              // along the unit ray direction
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  // unit outward surface normal at the hit
};

/// Planar rectangle z = slope_x * x + slope_y * y + offset_z over the xy rectangle
/// [x_min, x_max] x [y_min, y_max] (ground, ramps; large finite bounds make it "infinite-ish").
/// Two-sided; its outward normal points up.
class PlanePatch
{
public:
  /// Throws std::invalid_argument for non-finite or empty bounds.
  PlanePatch(double slope_x, double slope_y, double offset_z, double x_min, double x_max, double y_min, double y_max);
  static PlanePatch horizontal(double z, double x_min, double x_max, double y_min, double y_max);

  double heightAt(double x, double y) const { return slope_x_ * x + slope_y_ * y + offset_z_; }
  const Eigen::Vector3d& normal() const { return normal_; }
  /// Nearest hit with distance in (t_min, t_max); false if none.
  bool intersect(const Ray& ray, double t_min, double t_max, ShapeHit* hit) const;
  Aabb bounds() const;

private:
  double slope_x_;
  double slope_y_;
  double offset_z_;
  double x_min_;
  double x_max_;
  double y_min_;
  double y_max_;
  Eigen::Vector3d normal_;
};

/// Solid box with the given center and half extents, rotated by `yaw` about the vertical axis.
class OrientedBox
{
public:
  /// Throws std::invalid_argument for non-positive half extents.
  OrientedBox(const Eigen::Vector3d& center, const Eigen::Vector3d& half_extents, double yaw = 0.0);

  const Eigen::Vector3d& center() const { return center_; }
  const Eigen::Vector3d& halfExtents() const { return half_extents_; }
  double yaw() const { return yaw_; }
  bool intersect(const Ray& ray, double t_min, double t_max, ShapeHit* hit) const;
  Aabb bounds() const;

private:
  Eigen::Vector3d center_;
  Eigen::Vector3d half_extents_;
  double yaw_;
  double cos_yaw_;
  double sin_yaw_;
};

/// Solid vertical cylinder (pole, tree trunk) with flat caps at z_min and z_max.
class VerticalCylinder
{
public:
  /// Throws std::invalid_argument for a non-positive radius or z_max <= z_min.
  VerticalCylinder(double center_x, double center_y, double radius, double z_min, double z_max);

  double centerX() const { return center_x_; }
  double centerY() const { return center_y_; }
  double radius() const { return radius_; }
  double zMin() const { return z_min_; }
  double zMax() const { return z_max_; }
  bool intersect(const Ray& ray, double t_min, double t_max, ShapeHit* hit) const;
  Aabb bounds() const;

private:
  double center_x_;
  double center_y_;
  double radius_;
  double z_min_;
  double z_max_;
};

/// Solid sphere (tree crown, boulder).
class Sphere
{
public:
  /// Throws std::invalid_argument for a non-positive radius.
  Sphere(const Eigen::Vector3d& center, double radius);

  const Eigen::Vector3d& center() const { return center_; }
  double radius() const { return radius_; }
  bool intersect(const Ray& ray, double t_min, double t_max, ShapeHit* hit) const;
  Aabb bounds() const;

private:
  Eigen::Vector3d center_;
  double radius_;
};

using Shape = std::variant<PlanePatch, OrientedBox, VerticalCylinder, Sphere>;

/// Semantic class of a surface (ground truth for feature and segmentation tests).
enum class SurfaceClass : std::uint8_t
{
  Ground,
  Building,
  Vehicle,
  Pole,
  TreeTrunk,
  TreeCrown,
  Other
};

/// Typical lidar reflectivity in [0, 1] of a surface class.
double defaultReflectivity(SurfaceClass surface_class);

/// A shape with its semantic class and reflectivity.
struct Primitive
{
  Primitive(Shape shape_in, SurfaceClass surface_class_in);
  Primitive(Shape shape_in, SurfaceClass surface_class_in, double reflectivity_in);

  Shape shape;
  SurfaceClass surface_class;
  double reflectivity;  // in [0, 1]; drives the simulated intensity
};

/// Ray-vs-shape test for any shape alternative.
bool intersectShape(const Shape& shape, const Ray& ray, double t_min, double t_max, ShapeHit* hit);
Aabb shapeBounds(const Shape& shape);

/// Nearest surface along a ray in a scene.
struct Hit
{
  double distance = 0.0;                              // metres along the unit ray direction
  Eigen::Vector3d point = Eigen::Vector3d::Zero();    // hit point, scene (world) frame
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  // unit surface normal facing the ray origin
  int surface_id = -1;                                // index of the primitive in the scene
  SurfaceClass surface_class = SurfaceClass::Other;
};

/// Parameters of Scene::urbanStreet. Lengths in metres; *_min/*_max are uniform ranges.
struct UrbanStreetOptions
{
  double length_m = 300.0;           // the street centerline runs along +x from x = 0 to x = length_m
  double end_margin_m = 60.0;        // buildings and ground continue this far beyond both ends
  double ground_margin_m = 200.0;    // ground extends this far beyond the ends and from the centerline
  double street_width_min_m = 12.0;  // curb to curb
  double street_width_max_m = 16.0;
  double sidewalk_width_m = 3.0;  // curb to the nominal facade line
  double curb_height_m = 0.15;
  double sidewalk_segment_m = 20.0;  // sidewalks are split into slabs of this length
  double building_length_min_m = 10.0;
  double building_length_max_m = 35.0;
  double building_depth_min_m = 8.0;
  double building_depth_max_m = 16.0;
  double building_height_min_m = 6.0;
  double building_height_max_m = 25.0;
  double building_setback_max_m = 2.0;   // facade recess behind the nominal facade line
  double facade_step_probability = 0.3;  // a building is made of two blocks with different setbacks
  double gap_probability = 0.35;         // chance of an alley / gap after a building
  double gap_min_m = 2.0;
  double gap_max_m = 10.0;
  double car_slot_length_m = 6.5;  // parking slots along each curb
  double car_probability = 0.45;   // chance that a slot holds a parked car
  double pole_spacing_min_m = 15.0;
  double pole_spacing_max_m = 25.0;
  double pole_radius_min_m = 0.1;
  double pole_radius_max_m = 0.2;
  double pole_height_min_m = 4.0;
  double pole_height_max_m = 8.0;
  double tree_probability = 0.3;  // chance of a tree midway between two consecutive poles
  double trunk_radius_min_m = 0.15;
  double trunk_radius_max_m = 0.3;
  double trunk_height_min_m = 2.0;
  double trunk_height_max_m = 3.5;
  double crown_radius_min_m = 1.5;
  double crown_radius_max_m = 3.0;
};

/// A set of primitives with a uniform 2D grid over xy for fast ray queries. Primitives with a huge
/// footprint (ground) are kept in a separate list tested for every ray. Immutable during queries;
/// `intersect` is const and thread-safe.
class Scene
{
public:
  static constexpr double kDefaultCellSize = 4.0;  // metres, side of a grid cell

  explicit Scene(double cell_size_m = kDefaultCellSize);
  explicit Scene(std::vector<Primitive> primitives, double cell_size_m = kDefaultCellSize);

  /// Adds a primitive and returns its surface id (its index). Amortized cheap; the grid grows as
  /// needed.
  int add(Primitive primitive);
  int add(Shape shape, SurfaceClass surface_class);

  std::size_t size() const { return primitives_.size(); }
  const Primitive& primitive(int surface_id) const { return primitives_.at(static_cast<std::size_t>(surface_id)); }
  const std::vector<Primitive>& primitives() const { return primitives_; }
  /// Bounds of all primitives.
  const Aabb& bounds() const { return bounds_; }
  int countClass(SurfaceClass surface_class) const;

  /// Nearest hit along `direction` (any non-zero length) from `origin` within `max_range` metres;
  /// nullopt if nothing is hit or the direction is zero.
  std::optional<Hit> intersect(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction, double max_range) const;
  /// Same answer as `intersect`, testing every primitive (reference for tests).
  std::optional<Hit> intersectBruteForce(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                                         double max_range) const;

  /// Horizontal ground z = 0 over |x|, |y| <= half_extent_m.
  static Scene flatGround(double half_extent_m = 500.0);
  /// Flat ground plus one 4 x 6 x 3 m box centered at (10, 0), axis-aligned: faces at x = 8 and
  /// x = 12, y = +-3, top at z = 3.
  static Scene simpleBox();
  /// Deterministic street scene for a given seed: see UrbanStreetOptions. Ground at z = 0; a sensor
  /// on the centerline (y = 0, z around 1.8 m) is clear of all obstacles for x in [0, length_m].
  static Scene urbanStreet(unsigned seed, double length_m = 300.0);
  static Scene urbanStreet(unsigned seed, const UrbanStreetOptions& options);

private:
  // Tests one primitive and updates the nearest hit so far.
  void testPrimitive(int id, const Ray& ray, double* best_t, ShapeHit* best_hit, int* best_id) const;
  std::optional<Hit> makeHit(const Ray& ray, double t, const ShapeHit& shape_hit, int id) const;
  // Grid helpers.
  bool isLarge(const Aabb& box) const;
  void rebuildGrid(const Aabb& extent);
  void insertIntoGrid(int id);
  void cellRange(const Aabb& box, int* ix0, int* iy0, int* ix1, int* iy1) const;

  double cell_size_;
  std::vector<Primitive> primitives_;
  std::vector<Aabb> primitive_bounds_;  // parallel to primitives_
  std::vector<int> large_ids_;          // primitives tested for every ray
  std::vector<int> gridded_ids_;        // primitives stored in the grid
  Aabb bounds_;                         // all primitives
  Aabb gridded_bounds_;                 // primitives in the grid (rays are clipped to it)
  // Uniform grid over xy: cell (ix, iy) covers [grid_x0_ + ix * cell, ...) and likewise in y.
  double grid_x0_ = 0.0;
  double grid_y0_ = 0.0;
  int grid_nx_ = 0;
  int grid_ny_ = 0;
  std::vector<std::vector<int>> cells_;  // row-major, index iy * grid_nx_ + ix
};

}  // namespace sim
}  // namespace aloam
