#include "aloam_nodelet/core/voxel_filter.h"

#include <algorithm>
#include <array>
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

// Bits needed to write v >= 0.
int bitWidth(std::uint64_t v)
{
  int bits = 0;
  while (v != 0)
  {
    ++bits;
    v >>= 1;
  }
  return bits;
}

// Sorts (key, point index) pairs, given in index order, by the low `bits` bits of the key: a least
// significant digit radix sort, 8 bits a pass. Being stable, it keeps equal keys in index order, which
// is what sorting the pairs would give.
void radixSort(std::vector<std::pair<std::uint64_t, std::uint32_t>>& items, int bits)
{
  std::vector<std::pair<std::uint64_t, std::uint32_t>> buffer(items.size());
  for (int shift = 0; shift < bits; shift += 8)
  {
    std::array<std::size_t, 257> start{};
    for (const auto& item : items)
    {
      ++start[((item.first >> shift) & 0xFF) + 1];
    }
    for (std::size_t digit = 1; digit < start.size(); ++digit)
    {
      start[digit] += start[digit - 1];
    }
    for (const auto& item : items)
    {
      buffer[start[(item.first >> shift) & 0xFF]++] = item;
    }
    items.swap(buffer);
  }
}

// The voxel cells of the finite points of `in`, sorted by cell (x, then y, then z) and, within a cell, by
// point index. Cells are packed into one integer key, each axis in as many bits as the cloud's extent
// needs (a lidar sweep at 0.2-0.8 m leaves needs about 30 bits), and radix-sorted: much faster than
// comparing triples.
std::vector<VoxelEntry> sortedCells(const Cloud& in, double inverse_leaf)
{
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
  if (entries.empty())
  {
    return entries;
  }
  std::int64_t lo[3] = { entries[0].x, entries[0].y, entries[0].z };
  std::int64_t hi[3] = { lo[0], lo[1], lo[2] };
  for (const VoxelEntry& e : entries)
  {
    const std::int64_t c[3] = { e.x, e.y, e.z };
    for (int a = 0; a < 3; ++a)
    {
      lo[a] = std::min(lo[a], c[a]);
      hi[a] = std::max(hi[a], c[a]);
    }
  }
  int bits[3];
  for (int a = 0; a < 3; ++a)
  {
    bits[a] = bitWidth(static_cast<std::uint64_t>(hi[a] - lo[a]));
  }
  if (bits[0] + bits[1] + bits[2] > 63)  // also keeps every shift below 64
  {
    std::sort(entries.begin(), entries.end());
    return entries;
  }
  const int shift_x = bits[1] + bits[2], shift_y = bits[2];
  std::vector<std::pair<std::uint64_t, std::uint32_t>> keys;
  keys.reserve(entries.size());
  for (const VoxelEntry& e : entries)
  {
    const auto key =
        (std::uint64_t(e.x - lo[0]) << shift_x) | (std::uint64_t(e.y - lo[1]) << shift_y) | std::uint64_t(e.z - lo[2]);
    keys.emplace_back(key, e.index);
  }
  radixSort(keys, bits[0] + bits[1] + bits[2]);
  const auto mask = [](int n) { return (std::uint64_t(1) << n) - 1; };
  for (std::size_t i = 0; i < keys.size(); ++i)
  {
    const std::uint64_t key = keys[i].first;
    entries[i] = VoxelEntry{ static_cast<std::int32_t>(std::int64_t(key >> shift_x) + lo[0]),
                             static_cast<std::int32_t>(std::int64_t((key >> shift_y) & mask(bits[1])) + lo[1]),
                             static_cast<std::int32_t>(std::int64_t(key & mask(bits[2])) + lo[2]), keys[i].second };
  }
  return entries;
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

  const std::vector<VoxelEntry> entries = sortedCells(in, 1.0 / leaf_size);
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
