#include "aloam_nodelet/core/cube_map.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <tuple>

namespace aloam
{
namespace
{
// Voxel of a point; false when a coordinate is beyond the int32 voxel range.
bool voxelOf(const Point& p, double leaf_size, VoxelKey& key)
{
  // Same arithmetic as voxelDownsample, so that both agree on every voxel boundary.
  constexpr double kLimit = static_cast<double>(std::numeric_limits<std::int32_t>::max());
  const double inverse_leaf = 1.0 / leaf_size;
  const double x = std::floor(static_cast<double>(p.x) * inverse_leaf);
  const double y = std::floor(static_cast<double>(p.y) * inverse_leaf);
  const double z = std::floor(static_cast<double>(p.z) * inverse_leaf);
  if (!(std::fabs(x) < kLimit && std::fabs(y) < kLimit && std::fabs(z) < kLimit))
  {
    return false;
  }
  key = VoxelKey{ static_cast<std::int32_t>(x), static_cast<std::int32_t>(y), static_cast<std::int32_t>(z) };
  return true;
}

// A new point for an occupied voxel, averaged in once the whole batch is in.
struct PendingMerge
{
  Cloud* layer;
  std::uint32_t index;
  Point point;
};

// Each voxel that received points becomes the mean of its previous point and the new ones (the centroid
// downsampling the cube again would give, since the previous point stands for its voxel).
void applyMerges(std::vector<PendingMerge>& merges)
{
  std::stable_sort(merges.begin(), merges.end(),
                   [](const PendingMerge& a, const PendingMerge& b)
                   { return std::tie(a.layer, a.index) < std::tie(b.layer, b.index); });
  for (std::size_t begin = 0; begin < merges.size();)
  {
    Point& target = merges[begin].layer->points[merges[begin].index];
    double sx = target.x, sy = target.y, sz = target.z, si = target.intensity, st = target.time;
    std::size_t end = begin;
    for (; end < merges.size() && merges[end].layer == merges[begin].layer && merges[end].index == merges[begin].index;
         ++end)
    {
      const Point& p = merges[end].point;
      sx += p.x;
      sy += p.y;
      sz += p.z;
      si += p.intensity;
      st += p.time;
    }
    const double n = static_cast<double>(end - begin + 1);
    target.x = static_cast<float>(sx / n);
    target.y = static_cast<float>(sy / n);
    target.z = static_cast<float>(sz / n);
    target.intensity = static_cast<float>(si / n);
    target.time = static_cast<float>(st / n);
    begin = end;
  }
}

std::int64_t cellOf(double v, double size)
{
  const double c = std::floor(v / size);
  constexpr double kLimit = static_cast<double>(std::numeric_limits<std::int32_t>::max());
  return std::isfinite(c) ? static_cast<std::int64_t>(std::clamp(c, -kLimit, kLimit)) : 0;
}
}  // namespace

CubeMap::CubeMap(double cube_size, double corner_leaf_size, double surf_leaf_size)
  : cube_size_(cube_size), corner_leaf_size_(corner_leaf_size), surf_leaf_size_(surf_leaf_size)
{
  if (!(cube_size > 0.0) || !std::isfinite(cube_size))
  {
    throw std::invalid_argument("CubeMap: cube size must be a positive number");
  }
}

CubeIndex CubeMap::indexOf(const Eigen::Vector3d& p) const
{
  return CubeIndex{ cellOf(p.x(), cube_size_), cellOf(p.y(), cube_size_), cellOf(p.z(), cube_size_) };
}

Eigen::Vector3d CubeMap::centreOf(const CubeIndex& c) const
{
  return (Eigen::Vector3d(double(c.x), double(c.y), double(c.z)) + Eigen::Vector3d::Constant(0.5)) * cube_size_;
}

std::vector<CubeIndex> CubeMap::insert(const Cloud& world_points, bool corners, bool merge)
{
  const double leaf_size = corners ? corner_leaf_size_ : surf_leaf_size_;
  std::vector<CubeIndex> touched;
  std::vector<PendingMerge> merges;
  CubeIndex last_index;
  Cube* cube = nullptr;
  for (const Point& p : world_points.points)
  {
    if (!isFinite(p))
    {
      continue;
    }
    const CubeIndex index = indexOf(Eigen::Vector3d(p.x, p.y, p.z));
    if (cube == nullptr || index != last_index)
    {
      // Consecutive points mostly share a cube: look it up only when it changes.
      cube = &cubes_[index];
      last_index = index;
      if (std::find(touched.begin(), touched.end(), index) == touched.end())
      {
        touched.push_back(index);
      }
    }
    Cloud& layer = corners ? cube->corners : cube->surfs;
    VoxelKey key;
    if (!(leaf_size > 0.0))
    {
      layer.points.push_back(p);
      continue;
    }
    if (!voxelOf(p, leaf_size, key))
    {
      continue;
    }
    const auto [it, added] = (corners ? cube->corner_voxels : cube->surf_voxels)
                                 .try_emplace(key, static_cast<std::uint32_t>(layer.points.size()));
    if (added || !merge)
    {
      // Without merging (re-bucketing), a second point of a voxel stays as it is, unindexed.
      layer.points.push_back(p);
    }
    else
    {
      merges.push_back(PendingMerge{ &layer, it->second, p });
    }
  }
  applyMerges(merges);
  for (const CubeIndex& index : touched)
  {
    Cube& c = cubes_[index];
    setUnorganized(corners ? c.corners : c.surfs);
  }
  return touched;
}

void CubeMap::reindex(const Cloud& points, VoxelIndex& voxels, double leaf_size)
{
  voxels.clear();
  if (!(leaf_size > 0.0))
  {
    return;
  }
  // The first point of each voxel stands for it; the others stay as they are, unindexed.
  VoxelKey key;
  for (std::size_t i = 0; i < points.size(); ++i)
  {
    if (voxelOf(points.points[i], leaf_size, key))
    {
      voxels.emplace(key, static_cast<std::uint32_t>(i));
    }
  }
}

void CubeMap::setLeafSizes(double corner_leaf_size, double surf_leaf_size)
{
  if (corner_leaf_size == corner_leaf_size_ && surf_leaf_size == surf_leaf_size_)
  {
    return;
  }
  corner_leaf_size_ = corner_leaf_size;
  surf_leaf_size_ = surf_leaf_size;
  for (auto& [index, cube] : cubes_)
  {
    reindex(cube.corners, cube.corner_voxels, corner_leaf_size_);
    reindex(cube.surfs, cube.surf_voxels, surf_leaf_size_);
  }
}

std::vector<CubeIndex> CubeMap::insertCorners(const Cloud& world_points)
{
  return insert(world_points, true);
}

std::vector<CubeIndex> CubeMap::insertSurfs(const Cloud& world_points)
{
  return insert(world_points, false);
}

void CubeMap::setCubeSize(double cube_size)
{
  if (!(cube_size > 0.0) || !std::isfinite(cube_size))
  {
    throw std::invalid_argument("CubeMap: cube size must be a positive number");
  }
  if (cube_size == cube_size_)
  {
    return;
  }
  auto old = std::move(cubes_);
  cubes_.clear();
  cube_size_ = cube_size;
  for (const auto& [index, cube] : old)
  {
    // A voxel may straddle two cubes; its points must not merge when they come together.
    insert(cube.corners, true, false);
    insert(cube.surfs, false, false);
  }
}

void CubeMap::gather(const CubeIndex& centre, int half_xy, int half_z, Cloud& corners, Cloud& surfs) const
{
  for (std::int64_t i = centre.x - half_xy; i <= centre.x + half_xy; ++i)
  {
    for (std::int64_t j = centre.y - half_xy; j <= centre.y + half_xy; ++j)
    {
      for (std::int64_t k = centre.z - half_z; k <= centre.z + half_z; ++k)
      {
        const auto it = cubes_.find(CubeIndex{ i, j, k });
        if (it != cubes_.end())
        {
          corners.points.insert(corners.points.end(), it->second.corners.points.begin(),
                                it->second.corners.points.end());
          surfs.points.insert(surfs.points.end(), it->second.surfs.points.begin(), it->second.surfs.points.end());
        }
      }
    }
  }
  setUnorganized(corners);
  setUnorganized(surfs);
}

std::size_t CubeMap::evictBeyond(const Eigen::Vector3d& position, double radius)
{
  std::size_t removed = 0;
  for (auto it = cubes_.begin(); it != cubes_.end();)
  {
    const Eigen::Vector3d d = centreOf(it->first) - position;
    if (d.head<2>().norm() > radius)
    {
      it = cubes_.erase(it);
      ++removed;
    }
    else
    {
      ++it;
    }
  }
  return removed;
}

const CubeMap::Cube* CubeMap::find(const CubeIndex& index) const
{
  const auto it = cubes_.find(index);
  return it == cubes_.end() ? nullptr : &it->second;
}

std::size_t CubeMap::cornerCount() const
{
  std::size_t n = 0;
  for (const auto& [index, cube] : cubes_)
  {
    n += cube.corners.size();
  }
  return n;
}

std::size_t CubeMap::surfCount() const
{
  std::size_t n = 0;
  for (const auto& [index, cube] : cubes_)
  {
    n += cube.surfs.size();
  }
  return n;
}

void CubeMap::collectAll(Cloud& out) const
{
  for (const auto& [index, cube] : cubes_)
  {
    out.points.insert(out.points.end(), cube.corners.points.begin(), cube.corners.points.end());
  }
  for (const auto& [index, cube] : cubes_)
  {
    out.points.insert(out.points.end(), cube.surfs.points.begin(), cube.surfs.points.end());
  }
  setUnorganized(out);
}

}  // namespace aloam
