// The feature map: edge and plane points bucketed into cubes keyed by integer cube index.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <unordered_map>
#include <vector>

#include <Eigen/Core>

#include "aloam_nodelet/core/point_types.h"

namespace aloam
{
/// Integer cube coordinates: floor(position / cube_size) on each axis.
struct CubeIndex
{
  std::int64_t x = 0, y = 0, z = 0;

  bool operator==(const CubeIndex& o) const { return x == o.x && y == o.y && z == o.z; }
  bool operator!=(const CubeIndex& o) const { return !(*this == o); }
};

struct CubeIndexHash
{
  std::size_t operator()(const CubeIndex& c) const
  {
    // Large odd multipliers mix the three axes (as in spatial hashing of voxel grids).
    return static_cast<std::size_t>(c.x * 73856093LL ^ c.y * 19349669LL ^ c.z * 83492791LL);
  }
};

/// Integer voxel coordinates: floor(position / leaf size) on each axis.
struct VoxelKey
{
  std::int32_t x = 0, y = 0, z = 0;

  bool operator==(const VoxelKey& o) const { return x == o.x && y == o.y && z == o.z; }
};

struct VoxelKeyHash
{
  std::size_t operator()(const VoxelKey& v) const
  {
    return static_cast<std::size_t>(std::int64_t(v.x) * 73856093LL ^ std::int64_t(v.y) * 19349669LL ^
                                    std::int64_t(v.z) * 83492791LL);
  }
};

/// Sparse map of cubes, each holding the edge and plane points that fall in it (world frame).
/// No fixed grid: any finite position has a cube; cubes far from the robot can be evicted.
///
/// With a leaf size, each layer (edges, planes) keeps one point per voxel: a point landing in an occupied
/// voxel is averaged into it, as downsampling the cube after every insertion would (A-LOAM), but at the
/// cost of a hash look-up per new point instead of a sort of the whole cube.
class CubeMap
{
public:
  using VoxelIndex = std::unordered_map<VoxelKey, std::uint32_t, VoxelKeyHash>;
  struct Cube
  {
    Cloud corners;
    Cloud surfs;
    VoxelIndex corner_voxels;  ///< occupied voxel -> its point in `corners` (empty without a leaf size)
    VoxelIndex surf_voxels;
  };

  /// Leaf sizes <= 0 keep every point.
  explicit CubeMap(double cube_size = 50.0, double corner_leaf_size = 0.0, double surf_leaf_size = 0.0);

  double cubeSize() const { return cube_size_; }
  /// Changes the cube size and moves every point into its new cube; no point is lost.
  void setCubeSize(double cube_size);
  /// Changes the leaf sizes: later insertions merge at the new sizes; the points already in the map stay
  /// (none is lost, as with a new cube size).
  void setLeafSizes(double corner_leaf_size, double surf_leaf_size);

  /// Cube of a position. Non-finite positions map to the origin's cube (callers filter them first).
  CubeIndex indexOf(const Eigen::Vector3d& position) const;
  /// Centre of a cube in world coordinates.
  Eigen::Vector3d centreOf(const CubeIndex& index) const;

  /// Adds points to their cubes (merging them into occupied voxels); non-finite points are dropped.
  /// Returns the cubes that changed.
  std::vector<CubeIndex> insertCorners(const Cloud& world_points);
  std::vector<CubeIndex> insertSurfs(const Cloud& world_points);

  /// Appends the points of the cubes within +-half_xy (x, y) and +-half_z (z) cubes of `centre`.
  void gather(const CubeIndex& centre, int half_xy, int half_z, Cloud& corners, Cloud& surfs) const;

  /// Removes every cube whose centre is farther than `radius` from `position` (horizontal distance);
  /// returns the number of cubes removed.
  std::size_t evictBeyond(const Eigen::Vector3d& position, double radius);

  const Cube* find(const CubeIndex& index) const;
  std::size_t cubeCount() const { return cubes_.size(); }
  std::size_t cornerCount() const;
  std::size_t surfCount() const;
  /// Every point of the map, edges then planes.
  void collectAll(Cloud& out) const;
  void clear() { cubes_.clear(); }

  template <typename F>
  void forEachCube(F&& f) const
  {
    for (const auto& [index, cube] : cubes_)
    {
      f(index, cube);
    }
  }

private:
  double cube_size_;
  double corner_leaf_size_;
  double surf_leaf_size_;
  std::unordered_map<CubeIndex, Cube, CubeIndexHash> cubes_;

  std::vector<CubeIndex> insert(const Cloud& world_points, bool corners, bool merge = true);
  static void reindex(const Cloud& points, VoxelIndex& voxels, double leaf_size);
};

}  // namespace aloam
