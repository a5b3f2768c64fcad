#include "aloam_nodelet/core/voxel_filter.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numeric>
#include <tuple>
#include <utility>
#include <vector>

namespace aloam
{
namespace
{
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

// The filter's buffers, one set per thread, kept between calls: a sweep needs a few MB of them, and
// fresh allocations of that size came from the kernel page by page on every call.
struct Scratch
{
  std::vector<std::int32_t> cells;  // x, y, z cell of each finite point
  std::vector<std::uint32_t> index, index_tmp;
  std::vector<std::uint64_t> keys, keys_tmp;
};

// Sorts `keys` ascending by their low `bits` bits, moving `index` along; stable, so equal keys keep their
// order. A least significant digit radix sort with 11-bit digits whose histograms are counted in one
// pass; a digit every key shares is skipped. The result is left in `keys` and `index`.
void radixSort(Scratch& s, std::size_t n, int bits)
{
  constexpr int kDigitBits = 11;
  constexpr std::size_t kBuckets = std::size_t(1) << kDigitBits;
  const int digits = (bits + kDigitBits - 1) / kDigitBits;
  std::vector<std::array<std::uint32_t, kBuckets>> start(static_cast<std::size_t>(digits));
  for (auto& counts : start)
  {
    counts.fill(0);
  }
  for (std::size_t k = 0; k < n; ++k)
  {
    for (int d = 0; d < digits; ++d)
    {
      ++start[d][(s.keys[k] >> (d * kDigitBits)) & (kBuckets - 1)];
    }
  }
  s.keys_tmp.resize(n);
  s.index_tmp.resize(n);
  for (int d = 0; d < digits; ++d)
  {
    auto& next = start[d];
    if (std::find(next.begin(), next.end(), static_cast<std::uint32_t>(n)) != next.end())
    {
      continue;  // one bucket holds every key
    }
    std::uint32_t sum = 0;
    for (std::uint32_t& count : next)
    {
      sum += std::exchange(count, sum);
    }
    const int shift = d * kDigitBits;
    for (std::size_t k = 0; k < n; ++k)
    {
      const std::uint32_t to = next[(s.keys[k] >> shift) & (kBuckets - 1)]++;
      s.keys_tmp[to] = s.keys[k];
      s.index_tmp[to] = s.index[k];
    }
    s.keys.swap(s.keys_tmp);
    s.index.swap(s.index_tmp);
  }
}

// Orders the finite points of `in` by voxel (x, then y, then z cell) and, within a voxel, by point index:
// `s.index` gets the order and `s.keys` a value per point that differs exactly where the voxel does.
// Returns their number. Cells are packed into one integer key, each axis in as many bits as the cloud's
// extent needs (a lidar sweep at 0.2-0.8 m leaves needs about 30 bits), and radix-sorted: much faster
// than comparing triples (which a larger extent falls back to).
std::size_t sortByVoxel(const Cloud& in, double inverse_leaf, Scratch& s)
{
  s.cells.resize(3 * in.size());
  s.index.resize(in.size());
  std::size_t n = 0;
  std::int32_t lo[3] = { 0, 0, 0 }, hi[3] = { 0, 0, 0 };
  for (std::size_t i = 0; i < in.size(); ++i)
  {
    const Point& p = in.points[i];
    std::int32_t* cell = &s.cells[3 * n];
    if (!(isFinite(p) && cellOf(p.x, inverse_leaf, cell[0]) && cellOf(p.y, inverse_leaf, cell[1]) &&
          cellOf(p.z, inverse_leaf, cell[2])))
    {
      continue;
    }
    for (int a = 0; a < 3; ++a)
    {
      lo[a] = n == 0 ? cell[a] : std::min(lo[a], cell[a]);
      hi[a] = n == 0 ? cell[a] : std::max(hi[a], cell[a]);
    }
    s.index[n++] = static_cast<std::uint32_t>(i);
  }
  int bits[3];
  for (int a = 0; a < 3; ++a)
  {
    bits[a] = bitWidth(static_cast<std::uint64_t>(std::int64_t(hi[a]) - lo[a]));
  }
  s.keys.resize(n);
  if (bits[0] + bits[1] + bits[2] > 63)  // also keeps every shift below 64
  {
    std::vector<std::uint32_t> order(n);
    std::iota(order.begin(), order.end(), 0u);
    const auto cell = [&s](std::uint32_t k)
    { return std::tie(s.cells[3 * k], s.cells[3 * k + 1], s.cells[3 * k + 2]); };
    std::stable_sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) { return cell(a) < cell(b); });
    std::vector<std::uint32_t> index(n);
    std::uint64_t voxel = 0;
    for (std::size_t k = 0; k < n; ++k)
    {
      voxel += k > 0 && cell(order[k]) != cell(order[k - 1]) ? 1 : 0;
      index[k] = s.index[order[k]];
      s.keys[k] = voxel;
    }
    s.index.swap(index);
    return n;
  }
  const int shift_x = bits[1] + bits[2], shift_y = bits[2];
  for (std::size_t k = 0; k < n; ++k)
  {
    const std::int32_t* cell = &s.cells[3 * k];
    s.keys[k] = (std::uint64_t(std::int64_t(cell[0]) - lo[0]) << shift_x) |
                (std::uint64_t(std::int64_t(cell[1]) - lo[1]) << shift_y) |
                std::uint64_t(std::int64_t(cell[2]) - lo[2]);
  }
  radixSort(s, n, bits[0] + bits[1] + bits[2]);
  return n;
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

  thread_local Scratch scratch;
  const std::size_t n = sortByVoxel(in, 1.0 / leaf_size, scratch);
  const auto& keys = scratch.keys;
  const auto& index = scratch.index;
  for (std::size_t begin = 0; begin < n;)
  {
    std::size_t end = begin + 1;
    while (end < n && keys[end] == keys[begin])
    {
      ++end;
    }
    double sx = 0.0, sy = 0.0, sz = 0.0, si = 0.0, st = 0.0;
    for (std::size_t k = begin; k < end; ++k)
    {
      const Point& p = in.points[index[k]];
      sx += p.x;
      sy += p.y;
      sz += p.z;
      si += p.intensity;
      st += p.time;
    }
    const double count = static_cast<double>(end - begin);
    Point c = in.points[index[begin]];
    c.x = static_cast<float>(sx / count);
    c.y = static_cast<float>(sy / count);
    c.z = static_cast<float>(sz / count);
    c.intensity = static_cast<float>(si / count);
    c.time = static_cast<float>(st / count);
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
