#include "aloam_nodelet/core/voxel_filter.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

namespace aloam
{
namespace
{
struct VoxelEntry
{
  std::int32_t x, y, z;
  std::uint32_t index;

  bool sameVoxel(const VoxelEntry& o) const { return x == o.x && y == o.y && z == o.z; }
  bool operator<(const VoxelEntry& o) const
  {
    if (x != o.x)
    {
      return x < o.x;
    }
    if (y != o.y)
    {
      return y < o.y;
    }
    if (z != o.z)
    {
      return z < o.z;
    }
    return index < o.index;
  }
};

bool cellOf(float v, double inverse_leaf, std::int32_t& cell)
{
  const double c = std::floor(static_cast<double>(v) * inverse_leaf);
  if (!(std::fabs(c) < static_cast<double>(std::numeric_limits<std::int32_t>::max())))
  {
    return false;
  }
  cell = static_cast<std::int32_t>(c);
  return true;
}
}  // namespace

std::size_t voxelDownsample(const Cloud& in, double leaf_size, Cloud& out)
{
  const std::size_t before = out.size();
  if (!(leaf_size > 0.0))
  {
    for (const auto& p : in.points)
    {
      if (isFinite(p))
      {
        out.push_back(p);
      }
    }
    return out.size() - before;
  }

  const double inverse_leaf = 1.0 / leaf_size;
  std::vector<VoxelEntry> entries;
  entries.reserve(in.size());
  for (std::size_t i = 0; i < in.size(); ++i)
  {
    const Point& p = in.points[i];
    VoxelEntry e{ 0, 0, 0, static_cast<std::uint32_t>(i) };
    if (isFinite(p) && cellOf(p.x, inverse_leaf, e.x) && cellOf(p.y, inverse_leaf, e.y) &&
        cellOf(p.z, inverse_leaf, e.z))
    {
      entries.push_back(e);
    }
  }
  std::sort(entries.begin(), entries.end());

  out.points.reserve(before + entries.size());
  for (std::size_t begin = 0; begin < entries.size();)
  {
    std::size_t end = begin + 1;
    while (end < entries.size() && entries[end].sameVoxel(entries[begin]))
    {
      ++end;
    }
    double sx = 0.0, sy = 0.0, sz = 0.0, si = 0.0, st = 0.0;
    for (std::size_t k = begin; k < end; ++k)
    {
      const Point& p = in.points[entries[k].index];
      sx += p.x;
      sy += p.y;
      sz += p.z;
      si += p.intensity;
      st += p.time;
    }
    const double n = static_cast<double>(end - begin);
    Point c = in.points[entries[begin].index];
    c.x = static_cast<float>(sx / n);
    c.y = static_cast<float>(sy / n);
    c.z = static_cast<float>(sz / n);
    c.intensity = static_cast<float>(si / n);
    c.time = static_cast<float>(st / n);
    out.points.push_back(c);
    begin = end;
  }
  setUnorganized(out);
  return out.size() - before;
}

void voxelDownsampleInPlace(Cloud& cloud, double leaf_size)
{
  Cloud filtered;
  filtered.header = cloud.header;
  voxelDownsample(cloud, leaf_size, filtered);
  cloud.swap(filtered);
}

}  // namespace aloam
