// Tests of CubeMap: floor-based cube indices, insertion, submap gathering, re-bucketing and eviction.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <set>
#include <stdexcept>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>

#include "test_support.h"
#include "aloam_nodelet/core/cube_map.h"
#include "aloam_nodelet/core/voxel_filter.h"

namespace aloam
{
namespace
{
using test_support::cloudOf;
using test_support::makePoint;
constexpr double kCube = 50.0;
constexpr double kTolerance = 1e-9;

// `count` random points in a cube of half side `half_extent` around the origin.
Cloud randomCloud(std::size_t count, double half_extent, unsigned seed)
{
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-half_extent, half_extent);
  Cloud c;
  for (std::size_t i = 0; i < count; ++i)
  {
    c.push_back(makePoint(u(rng), u(rng), u(rng), 0, static_cast<float>(i)));
  }
  return c;
}

using IndexTuple = std::tuple<std::int64_t, std::int64_t, std::int64_t>;

IndexTuple tupleOf(const CubeIndex& c)
{
  return IndexTuple(c.x, c.y, c.z);
}

// Every point of every cube lies in the cube its own coordinates map to.
void expectPointsInTheirCubes(const CubeMap& map)
{
  std::size_t misplaced = 0;
  map.forEachCube(
      [&](const CubeIndex& index, const CubeMap::Cube& cube)
      {
        for (const Cloud* c : { &cube.corners, &cube.surfs })
        {
          for (const Point& p : c->points)
          {
            misplaced += map.indexOf(Eigen::Vector3d(p.x, p.y, p.z)) != index ? 1 : 0;
          }
        }
      });
  EXPECT_EQ(misplaced, 0u);
}
}  // namespace

// Cube indices are floor(x / size): negative coordinates and exact multiples land in the right cube.
TEST(CubeMapTest, FloorIndicesAtNegativeCoordinatesAndExactMultiples)
{
  const CubeMap map(kCube);
  const auto ix = [&](double x) { return map.indexOf(Eigen::Vector3d(x, 0.0, 0.0)).x; };
  EXPECT_EQ(ix(-0.0001), -1);
  EXPECT_EQ(ix(0.0), 0);
  EXPECT_EQ(ix(49.9999), 0);
  EXPECT_EQ(ix(50.0), 1);
  EXPECT_EQ(ix(-50.0), -1);
  EXPECT_EQ(ix(-50.0001), -2);
  EXPECT_EQ(ix(-100.0), -2);
  // The three axes are independent.
  const CubeIndex c = map.indexOf(Eigen::Vector3d(-0.0001, 50.0, -50.0001));
  EXPECT_EQ(c.x, -1);
  EXPECT_EQ(c.y, 1);
  EXPECT_EQ(c.z, -2);
}

// centreOf is the middle of the cube, and a cube's centre maps back to the same cube.
TEST(CubeMapTest, CentreOfCube)
{
  const CubeMap map(kCube);
  const Eigen::Vector3d origin_centre = map.centreOf(CubeIndex{ 0, 0, 0 });
  EXPECT_NEAR((origin_centre - Eigen::Vector3d(25.0, 25.0, 25.0)).norm(), 0.0, kTolerance);
  const Eigen::Vector3d c = map.centreOf(CubeIndex{ -1, 2, -3 });
  EXPECT_NEAR((c - Eigen::Vector3d(-25.0, 125.0, -125.0)).norm(), 0.0, kTolerance);
  for (const CubeIndex& index : { CubeIndex{ -7, 3, 0 }, CubeIndex{ 5, -5, -1 }, CubeIndex{ 0, -1, 2 } })
  {
    EXPECT_EQ(map.indexOf(map.centreOf(index)), index);
  }
}

// A non-positive or non-finite cube size is refused.
TEST(CubeMapTest, InvalidCubeSizeThrows)
{
  EXPECT_THROW(CubeMap(0.0), std::invalid_argument);
  EXPECT_THROW(CubeMap(-5.0), std::invalid_argument);
  EXPECT_THROW(CubeMap{ std::numeric_limits<double>::quiet_NaN() }, std::invalid_argument);
  CubeMap map(kCube);
  EXPECT_THROW(map.setCubeSize(0.0), std::invalid_argument);
  EXPECT_THROW(map.setCubeSize(std::numeric_limits<double>::infinity()), std::invalid_argument);
  EXPECT_DOUBLE_EQ(map.cubeSize(), kCube);
}

// Inserted points go to their cubes, touched cubes are reported once each, and gather returns exactly
// the points of the cubes within the half extents.
TEST(CubeMapTest, InsertAndGatherSubmap)
{
  CubeMap map(kCube);
  constexpr std::size_t kPoints = 3000;
  constexpr double kExtent = 180.0;
  const Cloud corners = randomCloud(kPoints, kExtent, 1);
  const Cloud surfs = randomCloud(kPoints, kExtent, 2);
  const std::vector<CubeIndex> touched_corners = map.insertCorners(corners);
  const std::vector<CubeIndex> touched_surfs = map.insertSurfs(surfs);
  EXPECT_EQ(map.cornerCount(), kPoints);
  EXPECT_EQ(map.surfCount(), kPoints);
  expectPointsInTheirCubes(map);

  // Touched cubes: no duplicates, and exactly the cubes that hold points of that kind.
  std::set<IndexTuple> expected_touched;
  for (const Point& p : corners.points)
  {
    expected_touched.insert(tupleOf(map.indexOf(Eigen::Vector3d(p.x, p.y, p.z))));
  }
  std::set<IndexTuple> reported;
  for (const CubeIndex& c : touched_corners)
  {
    reported.insert(tupleOf(c));
  }
  EXPECT_EQ(reported.size(), touched_corners.size());
  EXPECT_EQ(reported, expected_touched);
  EXPECT_FALSE(touched_surfs.empty());

  constexpr int kHalfXy = 1;
  constexpr int kHalfZ = 0;
  const CubeIndex centre{ -1, 1, 0 };
  Cloud got_corners, got_surfs;
  map.gather(centre, kHalfXy, kHalfZ, got_corners, got_surfs);
  const auto inside = [&](const Point& p)
  {
    const CubeIndex c = map.indexOf(Eigen::Vector3d(p.x, p.y, p.z));
    return std::abs(c.x - centre.x) <= kHalfXy && std::abs(c.y - centre.y) <= kHalfXy &&
           std::abs(c.z - centre.z) <= kHalfZ;
  };
  const auto expected_count = [&](const Cloud& c)
  { return static_cast<std::size_t>(std::count_if(c.points.begin(), c.points.end(), inside)); };
  EXPECT_GT(expected_count(corners), 0u);
  EXPECT_EQ(got_corners.size(), expected_count(corners));
  EXPECT_EQ(got_surfs.size(), expected_count(surfs));
  EXPECT_TRUE(std::all_of(got_corners.points.begin(), got_corners.points.end(), inside));
  EXPECT_TRUE(std::all_of(got_surfs.points.begin(), got_surfs.points.end(), inside));
  EXPECT_EQ(got_corners.width, got_corners.size());

  // gather appends rather than replacing.
  map.gather(centre, kHalfXy, kHalfZ, got_corners, got_surfs);
  EXPECT_EQ(got_corners.size(), 2 * expected_count(corners));

  // A submap far from every point is empty.
  Cloud none_corners, none_surfs;
  map.gather(CubeIndex{ 100, 100, 0 }, kHalfXy, kHalfZ, none_corners, none_surfs);
  EXPECT_TRUE(none_corners.empty());
  EXPECT_TRUE(none_surfs.empty());
}

// Changing the cube size re-buckets every point: none lost, each in the cube its coordinates imply.
TEST(CubeMapTest, SetCubeSizeRebucketsWithoutLoss)
{
  CubeMap map(kCube);
  constexpr std::size_t kPoints = 5000;
  map.insertCorners(randomCloud(kPoints, 230.0, 3));
  map.insertSurfs(randomCloud(2 * kPoints, 230.0, 4));
  const std::size_t cubes_before = map.cubeCount();
  for (const double size : { 17.3, 120.0, 0.7, kCube })
  {
    map.setCubeSize(size);
    EXPECT_DOUBLE_EQ(map.cubeSize(), size);
    EXPECT_EQ(map.cornerCount(), kPoints) << "cube size " << size;
    EXPECT_EQ(map.surfCount(), 2 * kPoints) << "cube size " << size;
    expectPointsInTheirCubes(map);
  }
  EXPECT_EQ(map.cubeCount(), cubes_before);
  // The same size again changes nothing.
  map.setCubeSize(kCube);
  EXPECT_EQ(map.cubeCount(), cubes_before);
  EXPECT_EQ(map.cornerCount(), kPoints);
}

// evictBeyond removes exactly the cubes whose centre is horizontally farther than the radius.
TEST(CubeMapTest, EvictBeyondRemovesOnlyFarCubes)
{
  CubeMap map(kCube);
  map.insertSurfs(randomCloud(4000, 400.0, 5));
  // A tall column of cubes right above the robot: vertical distance must not count.
  map.insertCorners(cloudOf({ makePoint(10.0, 10.0, 1000.0), makePoint(10.0, 10.0, -1000.0) }));
  const Eigen::Vector3d robot(30.0, -70.0, 0.0);
  constexpr double kRadius = 160.0;

  std::size_t expected_far = 0;
  std::set<IndexTuple> expected_kept;
  map.forEachCube(
      [&](const CubeIndex& index, const CubeMap::Cube&)
      {
        if ((map.centreOf(index) - robot).head<2>().norm() > kRadius)
        {
          ++expected_far;
        }
        else
        {
          expected_kept.insert(tupleOf(index));
        }
      });
  ASSERT_GT(expected_far, 0u);
  ASSERT_FALSE(expected_kept.empty());

  const std::size_t removed = map.evictBeyond(robot, kRadius);
  EXPECT_EQ(removed, expected_far);
  std::set<IndexTuple> kept;
  map.forEachCube([&](const CubeIndex& index, const CubeMap::Cube&) { kept.insert(tupleOf(index)); });
  EXPECT_EQ(kept, expected_kept);
  EXPECT_NE(map.find(map.indexOf(Eigen::Vector3d(10.0, 10.0, 1000.0))), nullptr);
  EXPECT_NE(map.find(map.indexOf(Eigen::Vector3d(10.0, 10.0, -1000.0))), nullptr);
  // A second eviction from the same place removes nothing more.
  EXPECT_EQ(map.evictBeyond(robot, kRadius), 0u);
}

// Non-finite points are dropped on insertion and do not create or touch cubes.
TEST(CubeMapTest, NonFinitePointsAreDropped)
{
  CubeMap map(kCube);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  Point bad_x = makePoint(1.0, 2.0, 3.0);
  bad_x.x = nan;
  Point bad_y = makePoint(1.0, 2.0, 3.0);
  bad_y.y = inf;
  Point bad_z = makePoint(1.0, 2.0, 3.0);
  bad_z.z = -inf;
  const std::vector<CubeIndex> touched = map.insertCorners(cloudOf({ bad_x, bad_y, bad_z }));
  EXPECT_TRUE(touched.empty());
  EXPECT_EQ(map.cubeCount(), 0u);
  EXPECT_EQ(map.cornerCount(), 0u);

  map.insertSurfs(cloudOf({ bad_x, makePoint(-60.0, 0.0, 0.0), bad_z }));
  EXPECT_EQ(map.surfCount(), 1u);
  EXPECT_EQ(map.cubeCount(), 1u);
  Cloud all;
  map.collectAll(all);
  ASSERT_EQ(all.size(), 1u);
  EXPECT_FLOAT_EQ(all.points[0].x, -60.0f);
  // A non-finite query position maps to the origin's cube, as documented.
  EXPECT_EQ(map.indexOf(Eigen::Vector3d(std::nan(""), 0.0, 0.0)), (CubeIndex{ 0, 0, 0 }));
}

// Points at 1e12 m (and the float limit) neither crash insertion, gathering, re-bucketing nor eviction.
TEST(CubeMapTest, HugeCoordinatesDoNotCrash)
{
  CubeMap map(kCube);
  constexpr double kHuge = 1e12;
  const double float_max = static_cast<double>(std::numeric_limits<float>::max());
  const Cloud huge = cloudOf({ makePoint(kHuge, 0.0, 0.0), makePoint(-kHuge, kHuge, -kHuge),
                               makePoint(float_max, -float_max, 0.0), makePoint(1.0, 1.0, 1.0) });
  map.insertCorners(huge);
  map.insertSurfs(huge);
  EXPECT_EQ(map.cornerCount(), huge.size());
  EXPECT_EQ(map.surfCount(), huge.size());
  expectPointsInTheirCubes(map);

  Cloud corners, surfs;
  map.gather(map.indexOf(Eigen::Vector3d(kHuge, 0.0, 0.0)), 2, 1, corners, surfs);
  EXPECT_GE(corners.size(), 1u);

  map.setCubeSize(1.0);
  EXPECT_EQ(map.cornerCount(), huge.size());
  expectPointsInTheirCubes(map);

  // Only the cube of the ordinary point is within reach of the origin.
  map.evictBeyond(Eigen::Vector3d::Zero(), 10.0);
  EXPECT_EQ(map.cornerCount(), 1u);
  EXPECT_EQ(map.surfCount(), 1u);
}

// With leaf sizes, inserting batch after batch leaves exactly what A-LOAM's "append, then downsample the
// cube" gives: each voxel holds the mean of its previous point and the batch's new points.
TEST(CubeMapTest, VoxelMergingMatchesDownsamplingAfterEveryBatch)
{
  constexpr double kCornerLeaf = 0.4, kSurfLeaf = 0.8;
  CubeMap map(kCube, kCornerLeaf, kSurfLeaf);
  // Reference per layer: the whole map as one cloud, downsampled after each batch (voxels never
  // straddle cubes here: 50 m is a multiple of both leaves).
  Cloud reference_corners, reference_surfs;
  for (unsigned batch = 0; batch < 4; ++batch)
  {
    const Cloud corners = randomCloud(3000, 12.0, 10 + batch);
    const Cloud surfs = randomCloud(3000, 30.0, 20 + batch);
    map.insertCorners(corners);
    map.insertSurfs(surfs);
    reference_corners.points.insert(reference_corners.points.end(), corners.points.begin(), corners.points.end());
    reference_surfs.points.insert(reference_surfs.points.end(), surfs.points.begin(), surfs.points.end());
    voxelDownsampleInPlace(reference_corners, kCornerLeaf);
    voxelDownsampleInPlace(reference_surfs, kSurfLeaf);
    ASSERT_EQ(map.cornerCount(), reference_corners.size()) << "batch " << batch;
    ASSERT_EQ(map.surfCount(), reference_surfs.size()) << "batch " << batch;
  }
  // Dense batches really merged (12 m cube of 0.4 m voxels, 12000 points: many shared voxels).
  EXPECT_LT(map.cornerCount(), 12000u);

  // Same points, same voxel means (compare after sorting both by position).
  Cloud all;
  map.collectAll(all);
  Cloud map_corners;
  map_corners.points.assign(all.points.begin(), all.points.begin() + map.cornerCount());
  const auto byPosition = [](const Point& a, const Point& b)
  { return std::tie(a.x, a.y, a.z) < std::tie(b.x, b.y, b.z); };
  // Downsample again at a tiny leaf: a no-op that sorts both clouds the same way.
  std::sort(map_corners.points.begin(), map_corners.points.end(), byPosition);
  std::sort(reference_corners.points.begin(), reference_corners.points.end(), byPosition);
  std::size_t far = 0;
  for (std::size_t i = 0; i < map_corners.size(); ++i)
  {
    const Point& a = map_corners.points[i];
    const Point& b = reference_corners.points[i];
    far += std::fabs(a.x - b.x) + std::fabs(a.y - b.y) + std::fabs(a.z - b.z) > 1e-4f ? 1 : 0;
  }
  EXPECT_EQ(far, 0u);
  expectPointsInTheirCubes(map);
}

// New leaf sizes keep every point and apply to later insertions; re-bucketing with leaves keeps every
// point too.
TEST(CubeMapTest, SetLeafSizesAndRebucketingKeepPoints)
{
  CubeMap map(kCube);
  map.insertSurfs(randomCloud(20000, 20.0, 7));
  EXPECT_EQ(map.surfCount(), 20000u);
  map.setLeafSizes(0.4, 2.0);
  EXPECT_EQ(map.surfCount(), 20000u);
  // The same points again: each lands in an indexed 2 m voxel and merges, nothing is added.
  map.insertSurfs(randomCloud(20000, 20.0, 7));
  EXPECT_EQ(map.surfCount(), 20000u);
  // A new batch elsewhere is downsampled at 2 m.
  Cloud far = randomCloud(5000, 20.0, 8);
  for (Point& p : far.points)
  {
    p.x += 200.0f;
  }
  map.insertSurfs(far);
  Cloud reference = far;
  voxelDownsampleInPlace(reference, 2.0);
  EXPECT_EQ(map.surfCount(), 20000u + reference.size());
  const std::size_t surfs = map.surfCount();
  map.setCubeSize(7.3);  // 7.3 m is no multiple of 2 m: voxels straddle cubes, no point may merge
  EXPECT_EQ(map.surfCount(), surfs);
  expectPointsInTheirCubes(map);
  // Later insertions still merge into the re-bucketed voxels (except where a voxel's point now lies in
  // the neighbouring cube: voxels are per cube, as in A-LOAM).
  map.insertSurfs(randomCloud(20000, 20.0, 7));
  EXPECT_LT(map.surfCount(), surfs + 20000 / 4);
  expectPointsInTheirCubes(map);
}

}  // namespace aloam
