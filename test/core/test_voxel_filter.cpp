// Tests of voxelDownsample: one centroid per occupied voxel, leaf alignment, non-finite input, huge extents.
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <random>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>

#include "test_support.h"
#include "aloam_nodelet/core/voxel_filter.h"

namespace aloam
{
namespace
{
using test_support::cloudOf;
using test_support::makePoint;
constexpr double kLeaf = 0.2;
constexpr float kCoordinateTolerance = 1e-5f;

using Voxel = std::tuple<std::int64_t, std::int64_t, std::int64_t>;

Voxel voxelOf(const Point& p, double leaf)
{
  return Voxel(static_cast<std::int64_t>(std::floor(double(p.x) / leaf)),
               static_cast<std::int64_t>(std::floor(double(p.y) / leaf)),
               static_cast<std::int64_t>(std::floor(double(p.z) / leaf)));
}

// Reference: centroid of each voxel by a map from voxel to sums (independent of the implementation).
std::map<Voxel, std::array<double, 4>> referenceCentroids(const Cloud& in, double leaf)
{
  std::map<Voxel, std::array<double, 4>> sums;
  for (const Point& p : in.points)
  {
    auto& s = sums[voxelOf(p, leaf)];
    s[0] += p.x;
    s[1] += p.y;
    s[2] += p.z;
    s[3] += 1.0;
  }
  return sums;
}
}  // namespace

// Hand-made points: one output per occupied voxel at the centroid; intensity and time averaged, ring of
// the first point.
TEST(VoxelFilterTest, OneCentroidPerOccupiedVoxel)
{
  const Cloud in = cloudOf({
      makePoint(0.05, 0.05, 0.05, 3, 10.0f, 0.01f),   // voxel (0, 0, 0)
      makePoint(0.15, 0.11, 0.07, 4, 30.0f, 0.03f),   // voxel (0, 0, 0)
      makePoint(0.10, 0.02, 0.18, 5, 20.0f, 0.05f),   // voxel (0, 0, 0)
      makePoint(1.05, 0.05, 0.05, 9, 7.0f, 0.02f),    // voxel (5, 0, 0)
      makePoint(-0.05, -0.05, -0.05, 1, 1.0f, 0.0f),  // voxel (-1, -1, -1)
      makePoint(-0.15, -0.19, -0.01, 2, 3.0f, 0.1f),  // voxel (-1, -1, -1)
  });
  Cloud out;
  EXPECT_EQ(voxelDownsample(in, kLeaf, out), 3u);
  ASSERT_EQ(out.size(), 3u);
  EXPECT_EQ(out.width, 3u);
  EXPECT_EQ(out.height, 1u);

  int matched = 0;
  for (const Point& p : out.points)
  {
    const Voxel v = voxelOf(p, kLeaf);
    if (v == Voxel(0, 0, 0))
    {
      EXPECT_NEAR(p.x, 0.1f, kCoordinateTolerance);
      EXPECT_NEAR(p.y, 0.06f, kCoordinateTolerance);
      EXPECT_NEAR(p.z, 0.1f, kCoordinateTolerance);
      EXPECT_NEAR(p.intensity, 20.0f, kCoordinateTolerance);
      EXPECT_NEAR(p.time, 0.03f, kCoordinateTolerance);
      EXPECT_EQ(p.ring, 3);
      ++matched;
    }
    else if (v == Voxel(5, 0, 0))
    {
      EXPECT_NEAR(p.x, 1.05f, kCoordinateTolerance);
      EXPECT_EQ(p.ring, 9);
      EXPECT_NEAR(p.intensity, 7.0f, kCoordinateTolerance);
      ++matched;
    }
    else if (v == Voxel(-1, -1, -1))
    {
      EXPECT_NEAR(p.x, -0.1f, kCoordinateTolerance);
      EXPECT_NEAR(p.y, -0.12f, kCoordinateTolerance);
      EXPECT_NEAR(p.z, -0.03f, kCoordinateTolerance);
      EXPECT_NEAR(p.time, 0.05f, kCoordinateTolerance);
      EXPECT_EQ(p.ring, 1);
      ++matched;
    }
  }
  EXPECT_EQ(matched, 3);
}

// Voxels are aligned to multiples of the leaf: 0.19 / 0.21 and -0.01 / 0.01 are split, 0.01 / 0.19 are not.
TEST(VoxelFilterTest, VoxelsAlignToMultiplesOfTheLeaf)
{
  const auto count = [](std::vector<double> xs)
  {
    Cloud in;
    for (const double x : xs)
    {
      in.push_back(makePoint(x, 0.5, 0.5));
    }
    Cloud out;
    return voxelDownsample(in, kLeaf, out);
  };
  EXPECT_EQ(count({ 0.19, 0.21 }), 2u);
  EXPECT_EQ(count({ -0.01, 0.01 }), 2u);
  EXPECT_EQ(count({ 0.01, 0.19 }), 1u);
  EXPECT_EQ(count({ -0.19, -0.01 }), 1u);
  EXPECT_EQ(count({ 0.39, 0.41, 0.59, 0.61 }), 3u);
  // The same along y and z.
  Cloud in = cloudOf(
      { makePoint(0.5, 0.19, 0.5), makePoint(0.5, 0.21, 0.5), makePoint(0.5, 0.5, 0.19), makePoint(0.5, 0.5, 0.21) });
  Cloud out;
  EXPECT_EQ(voxelDownsample(in, kLeaf, out), 4u);
}

// Non-finite points are dropped; a leaf <= 0 copies the finite points in order.
TEST(VoxelFilterTest, NonFiniteDroppedAndNonPositiveLeafCopies)
{
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  const Cloud in = cloudOf({ makePoint(1.0, 1.0, 1.0), makePoint(nan, 0.0, 0.0), makePoint(1.01, 1.01, 1.01),
                             makePoint(0.0, inf, 0.0), makePoint(0.0, 0.0, -inf), makePoint(5.0, 5.0, 5.0) });
  Cloud out;
  EXPECT_EQ(voxelDownsample(in, kLeaf, out), 2u);
  for (const Point& p : out.points)
  {
    EXPECT_TRUE(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z));
  }

  for (const double leaf : { 0.0, -1.0 })
  {
    Cloud copy;
    EXPECT_EQ(voxelDownsample(in, leaf, copy), 3u);
    ASSERT_EQ(copy.size(), 3u);
    EXPECT_FLOAT_EQ(copy.points[0].x, 1.0f);
    EXPECT_FLOAT_EQ(copy.points[1].x, 1.01f);
    EXPECT_FLOAT_EQ(copy.points[2].x, 5.0f);
  }

  Cloud only_nan = cloudOf({ makePoint(nan, nan, nan) });
  Cloud nothing;
  EXPECT_EQ(voxelDownsample(only_nan, kLeaf, nothing), 0u);
  EXPECT_TRUE(nothing.empty());
}

// The output is appended to whatever `out` holds; the in-place variant filters the cloud itself.
TEST(VoxelFilterTest, AppendsAndFiltersInPlace)
{
  const Cloud in = cloudOf({ makePoint(0.01, 0.01, 0.01), makePoint(0.02, 0.02, 0.02), makePoint(3.0, 3.0, 3.0) });
  Cloud out = cloudOf({ makePoint(-7.0, -7.0, -7.0) });
  EXPECT_EQ(voxelDownsample(in, kLeaf, out), 2u);
  ASSERT_EQ(out.size(), 3u);
  EXPECT_FLOAT_EQ(out.points[0].x, -7.0f);
  EXPECT_EQ(out.width, 3u);

  Cloud cloud = in;
  voxelDownsampleInPlace(cloud, kLeaf);
  EXPECT_EQ(cloud.size(), 2u);
}

// A random cloud agrees with an independent voxel reference: same voxels, same centroids.
TEST(VoxelFilterTest, MatchesReferenceOnRandomCloud)
{
  std::mt19937 rng(42);
  std::uniform_real_distribution<double> u(-3.0, 3.0);
  Cloud in;
  constexpr int kPoints = 20000;
  for (int i = 0; i < kPoints; ++i)
  {
    in.push_back(makePoint(u(rng), u(rng), 0.1 * u(rng)));
  }
  constexpr double kLeafHere = 0.37;
  const auto reference = referenceCentroids(in, kLeafHere);
  Cloud out;
  voxelDownsample(in, kLeafHere, out);
  ASSERT_EQ(out.size(), reference.size());
  std::map<Voxel, int> seen;
  for (const Point& p : out.points)
  {
    const Voxel v = voxelOf(p, kLeafHere);
    ++seen[v];
    const auto it = reference.find(v);
    ASSERT_NE(it, reference.end());
    const auto& s = it->second;
    EXPECT_NEAR(p.x, s[0] / s[3], kCoordinateTolerance);
    EXPECT_NEAR(p.y, s[1] / s[3], kCoordinateTolerance);
    EXPECT_NEAR(p.z, s[2] / s[3], kCoordinateTolerance);
  }
  for (const auto& [v, n] : seen)
  {
    EXPECT_EQ(n, 1);
  }
}

// The output comes in voxel order (x, then y, then z cell), and a voxel's ring is its first point's: the
// stages' results depend on that order (sums in the solves), so it must not change with the sorting.
// Both sortings: the packed keys, and the triples of an extent too wide to pack.
TEST(VoxelFilterTest, OutputInVoxelOrder)
{
  for (const double far : { 0.0, 1e9 })
  {
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-5.0, 5.0);
    Cloud in;
    for (int i = 0; i < 5000; ++i)
    {
      in.push_back(makePoint(u(rng), u(rng), u(rng), i % 64));
    }
    in.push_back(makePoint(far, far, -far, 99));
    constexpr double kLeafHere = 0.5;
    Cloud out;
    voxelDownsample(in, kLeafHere, out);
    std::map<Voxel, int> first_ring;
    for (const Point& p : in.points)
    {
      first_ring.emplace(voxelOf(p, kLeafHere), p.ring);
    }
    ASSERT_EQ(out.size(), first_ring.size()) << "far " << far;
    std::size_t k = 0;
    for (const auto& [voxel, ring] : first_ring)  // std::map iterates in (x, y, z) order
    {
      EXPECT_EQ(voxelOf(out.points[k], kLeafHere), voxel) << "output " << k << ", far " << far;
      EXPECT_EQ(out.points[k].ring, ring) << "output " << k << ", far " << far;
      ++k;
    }
  }
}

// A cloud spanning 1e6 m with a 0.01 m leaf (1e8 voxels per axis, beyond pcl::VoxelGrid's int32 index)
// is filtered correctly.
TEST(VoxelFilterTest, HugeExtentWithTinyLeaf)
{
  constexpr double kTinyLeaf = 0.01;
  constexpr double kSpan = 1e6;
  const Cloud in = cloudOf({
      makePoint(0.001, 0.001, 0.001),  // these two share a voxel
      makePoint(0.005, 0.005, 0.005),
      makePoint(0.015, 0.001, 0.001),  // the next voxel along x
      makePoint(kSpan, 0.0, 0.0),
      makePoint(0.0, kSpan, 0.0),
      makePoint(0.0, 0.0, kSpan),
      makePoint(kSpan, kSpan, kSpan),
  });
  Cloud out;
  EXPECT_EQ(voxelDownsample(in, kTinyLeaf, out), 6u);
  int merged = 0;
  for (const Point& p : out.points)
  {
    if (std::fabs(p.x - 0.003f) < kCoordinateTolerance)
    {
      EXPECT_NEAR(p.y, 0.003f, kCoordinateTolerance);
      ++merged;
    }
  }
  EXPECT_EQ(merged, 1);
}

}  // namespace aloam
