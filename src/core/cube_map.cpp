#include "aloam_nodelet/core/cube_map.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace aloam
{
namespace
{
std::int64_t cellOf(double v, double size)
{
  const double c = std::floor(v / size);
  constexpr double kLimit = static_cast<double>(std::numeric_limits<std::int32_t>::max());
  return std::isfinite(c) ? static_cast<std::int64_t>(std::clamp(c, -kLimit, kLimit)) : 0;
}
}  // namespace

CubeMap::CubeMap(double cube_size) : cube_size_(cube_size)
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

std::vector<CubeIndex> CubeMap::insert(const Cloud& world_points, bool corners)
{
  std::vector<CubeIndex> touched;
  for (const Point& p : world_points.points)
  {
    if (!isFinite(p))
    {
      continue;
    }
    const CubeIndex index = indexOf(Eigen::Vector3d(p.x, p.y, p.z));
    Cube& cube = cubes_[index];
    (corners ? cube.corners : cube.surfs).points.push_back(p);
    if (std::find(touched.begin(), touched.end(), index) == touched.end())
    {
      touched.push_back(index);
    }
  }
  for (const CubeIndex& index : touched)
  {
    Cube& cube = cubes_[index];
    setUnorganized(corners ? cube.corners : cube.surfs);
  }
  return touched;
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
    insert(cube.corners, true);
    insert(cube.surfs, false);
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

CubeMap::Cube* CubeMap::find(const CubeIndex& index)
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
