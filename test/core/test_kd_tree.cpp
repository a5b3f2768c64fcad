// Tests of KdTree against brute force: nearest, k nearest, the radius bound, skipping, index ranges,
// duplicates and non-finite points.
#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "test_support.h"
#include "aloam_nodelet/core/kd_tree.h"

namespace aloam
{
namespace
{
using test_support::cloudOf;
using test_support::makePoint;

// Points clustered like lidar features: a few dense blobs plus a uniform background.
Cloud clusteredCloud(std::size_t count, unsigned seed)
{
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> uniform(-30.0, 30.0);
  std::normal_distribution<double> blob(0.0, 0.7);
  Cloud cloud;
  for (std::size_t i = 0; i < count; ++i)
  {
    if (i % 3 == 0)
    {
      cloud.push_back(makePoint(uniform(rng), uniform(rng), uniform(rng) / 10.0));
    }
    else
    {
      const double cx = 5.0 * double(i % 7), cy = -4.0 * double(i % 5);
      cloud.push_back(makePoint(cx + blob(rng), cy + blob(rng), blob(rng)));
    }
  }
  return cloud;
}

float squaredDistance(const Point& a, const Point& b)
{
  const float dx = a.x - b.x, dy = a.y - b.y, dz = a.z - b.z;
  return dx * dx + dy * dy + dz * dz;
}

// Brute force: (squared distance, index) of the points in [begin, end) below the bound, nearest first.
std::vector<std::pair<float, int>> bruteForce(const Cloud& cloud, const Point& q, float max_sq, int begin, int end,
                                              int skip = -1)
{
  std::vector<std::pair<float, int>> found;
  for (int i = begin; i < end; ++i)
  {
    const float d = squaredDistance(cloud.points[i], q);
    if (i != skip && isFinite(cloud.points[i]) && d < max_sq)
    {
      found.emplace_back(d, i);
    }
  }
  std::sort(found.begin(), found.end());
  return found;
}

TEST(KdTree, NearestMatchesBruteForce)
{
  const Cloud cloud = clusteredCloud(5000, 1);
  const Cloud queries = clusteredCloud(500, 2);
  KdTree tree;
  tree.build(cloud);
  ASSERT_EQ(tree.size(), cloud.size());
  int found_some = 0, found_none = 0;
  for (const float max_sq : { 0.05f, 1.0f, 25.0f })
  {
    for (const Point& q : queries.points)
    {
      const auto expected = bruteForce(cloud, q, max_sq, 0, int(cloud.size()));
      float d = -1.0f;
      const int got = tree.nearest(q, max_sq, &d);
      if (expected.empty())
      {
        EXPECT_EQ(got, -1);
        ++found_none;
        continue;
      }
      ASSERT_GE(got, 0);
      ++found_some;
      // Ties may pick either point; the distance must be the minimum.
      EXPECT_FLOAT_EQ(d, expected.front().first);
      EXPECT_FLOAT_EQ(squaredDistance(cloud.points[got], q), expected.front().first);
    }
  }
  // Both outcomes were exercised.
  EXPECT_GT(found_some, 100);
  EXPECT_GT(found_none, 10);
}

TEST(KdTree, KNearestMatchesBruteForceNearestFirst)
{
  const Cloud cloud = clusteredCloud(4000, 3);
  const Cloud queries = clusteredCloud(300, 4);
  KdTree tree;
  tree.build(cloud);
  std::vector<int> index;
  std::vector<float> sq;
  int partial = 0;
  for (const int k : { 1, 5, 12 })
  {
    for (const float max_sq : { 0.5f, 2.0f, 1e9f })
    {
      for (const Point& q : queries.points)
      {
        const auto expected = bruteForce(cloud, q, max_sq, 0, int(cloud.size()));
        const int n = tree.nearestK(q, k, max_sq, index, sq);
        const int want = std::min<int>(k, int(expected.size()));
        ASSERT_EQ(n, want);
        ASSERT_EQ(index.size(), std::size_t(n));
        ASSERT_EQ(sq.size(), std::size_t(n));
        partial += n < k;
        for (int i = 0; i < n; ++i)
        {
          EXPECT_FLOAT_EQ(sq[i], expected[i].first) << "k=" << k << " i=" << i;
          EXPECT_FLOAT_EQ(squaredDistance(cloud.points[index[i]], q), sq[i]);
          if (i > 0)
          {
            EXPECT_LE(sq[i - 1], sq[i]);
          }
        }
      }
    }
  }
  EXPECT_GT(partial, 10);  // the bound really cut some searches short
}

TEST(KdTree, RangeAndSkipReturnCloudIndices)
{
  const Cloud cloud = clusteredCloud(3000, 5);
  const int begin = 1000, end = 2000;
  KdTree tree;
  tree.build(cloud, begin, end);
  ASSERT_EQ(tree.size(), std::size_t(end - begin));
  for (int i = 0; i < 200; ++i)
  {
    // Query at an indexed point: skipping it must return the nearest *other* point.
    const int self = begin + 5 * i;
    const Point& q = cloud.points[self];
    EXPECT_EQ(tree.nearest(q, 1e9f), self);
    const auto expected = bruteForce(cloud, q, 1e9f, begin, end, self);
    float d = 0.0f;
    const int other = tree.nearest(q, 1e9f, &d, self);
    ASSERT_GE(other, begin);
    ASSERT_LT(other, end);
    EXPECT_NE(other, self);
    EXPECT_FLOAT_EQ(d, expected.front().first);
  }
}

TEST(KdTree, DuplicatesNonFiniteAndEmpty)
{
  const float nan = std::numeric_limits<float>::quiet_NaN();
  Cloud cloud;
  for (int i = 0; i < 50; ++i)
  {
    cloud.push_back(makePoint(1.0, 2.0, 3.0));  // fifty identical points
  }
  Point bad = makePoint(0.0, 0.0, 0.0);
  bad.x = nan;
  cloud.push_back(bad);
  cloud.push_back(makePoint(10.0, 0.0, 0.0));

  KdTree tree;
  tree.build(cloud);
  EXPECT_EQ(tree.size(), 51u);  // the NaN point is not indexed
  std::vector<int> index;
  std::vector<float> sq;
  EXPECT_EQ(tree.nearestK(makePoint(1.0, 2.0, 3.0), 20, 1.0f, index, sq), 20);
  for (const float d : sq)
  {
    EXPECT_EQ(d, 0.0f);
  }
  EXPECT_EQ(tree.nearest(makePoint(10.0, 0.0, 0.1), 1.0f), 51);
  EXPECT_EQ(tree.nearest(bad, 1e9f), -1);  // a non-finite query finds nothing
  EXPECT_EQ(tree.nearestK(makePoint(1.0, 2.0, 3.0), 0, 1.0f, index, sq), 0);

  KdTree empty;
  empty.build(Cloud());
  EXPECT_TRUE(empty.empty());
  EXPECT_EQ(empty.nearest(makePoint(0.0, 0.0, 0.0), 1e9f), -1);
  EXPECT_EQ(empty.nearestK(makePoint(0.0, 0.0, 0.0), 5, 1e9f, index, sq), 0);
  EXPECT_TRUE(index.empty());

  // Rebuilding reuses the object: the old points are gone.
  tree.build(cloudOf({ makePoint(-5.0, 0.0, 0.0) }));
  EXPECT_EQ(tree.size(), 1u);
  EXPECT_EQ(tree.nearest(makePoint(1.0, 2.0, 3.0), 1e9f), 0);
}

}  // namespace
}  // namespace aloam
