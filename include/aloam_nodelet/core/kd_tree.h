// A static 3-D kd-tree for the exact, radius-bounded neighbour queries of odometry and mapping.
#pragma once

#include <cstddef>
#include <vector>

#include "aloam_nodelet/core/point_types.h"

namespace aloam
{
/// Indexes the positions of a cloud (or of a contiguous range of it, e.g. one ring) and answers
/// nearest and k-nearest queries limited to a squared radius. Every query is exact. The bound matters
/// for speed: LOAM only wants neighbours within a metre or two, and a bounded search stops as soon as
/// no closer point can exist, where an unbounded one keeps descending for a far k-th neighbour.
/// Queries are const and may run concurrently; build() reuses its buffers.
///
/// Leaves keep their coordinates axis by axis (the distance loop vectorizes) and hold 32 points: against
/// the former point-by-point leaves of 16 (2026-12-02, medians of 3 interleaved runs of aloam_kd_tree_bench,
/// idle machine, before/after) per query 337/246 ns (odometry edges, nearest), 425/374 (odometry planes),
/// 719/554 (map edges, 5 nearest), 574/418 (map planes); builds 0.55/0.43, 2.81/2.46, 3.63/3.09,
/// 1.67/1.37 ms. The figures below are of the former leaves.
///
/// Measured against nanoflann 1.4.3 (Debian's libnanoflann-dev, same leaf size 16, the same interface over
/// it; issue 13, commit 5b53f83), KITTI 00 0-100, loaded 2-core machine, medians of 7 interleaved runs of
/// aloam_kd_tree_bench, own/nanoflann: build 0.69/0.68 ms (odometry edges, 5.2k points), 3.9/4.0 (odometry
/// planes, 29k), 4.3/4.7 (map edges, 31k), 1.7/2.2 (map planes, 16k); per query 362/357 ns, 643/422 ns
/// (nearest, 25 m^2), 834/905 ns, 561/801 ns (5 nearest, 2 m^2). End to end (aloam_bench --only kitti,
/// thread CPU ms) odometry 5.3/5.1, mapping 10.3/9.2: within noise; poses identical. Kept our own because
/// nanoflann cannot be a dependency for most of our users: its rosdep key (`nanoflann`, ros/rosdistro
/// #35852, 2023) resolves only from Ubuntu 22.04 on; Noetic's Ubuntu 20.04 has no package. The mapping
/// queries, the most numerous on the pose path, are also faster here. Pruning by each node's tight point
/// bounds instead of the split cells (as nanoflann does) measured no faster on these clouds.
class KdTree
{
public:
  /// Indexes every finite point of `cloud`.
  void build(const Cloud& cloud);
  /// Indexes the finite points of `cloud` with index in [begin, end). Query results are cloud indices.
  void build(const Cloud& cloud, int begin, int end);
  void clear();

  std::size_t size() const { return entries_.size(); }
  bool empty() const { return entries_.empty(); }

  /// The nearest indexed point other than `skip` with squared distance below `max_sq_distance`, or -1.
  /// Its squared distance goes to `*sq_distance` when given.
  int nearest(const Point& query, float max_sq_distance, float* sq_distance = nullptr, int skip = -1) const;

  /// The (at most) k nearest points with squared distance below `max_sq_distance`, nearest first.
  /// Returns how many were found; `index` and `sq_distance` are resized to that count.
  int nearestK(const Point& query, int k, float max_sq_distance, std::vector<int>& index,
               std::vector<float>& sq_distance) const;

private:
  struct Entry
  {
    float p[3];
    int index;  // into the indexed cloud
  };
  class Candidates;
  struct Node
  {
    int begin, end;  // entries of the subtree
    int left = -1;   // children (node indices); -1 for a leaf
    int right = -1;
    int axis = 0;
    float split = 0.0f;
  };
  struct Box
  {
    float lo[3], hi[3];
  };
  std::vector<Entry> entries_;
  std::vector<float> coordinates_[3];  // entries_' x, y and z apart, for the leaf scans
  std::vector<Node> nodes_;

  int buildNode(int begin, int end, const Box& box);
  /// `cell_sq`: squared distance from the query to the node's cell; `offset`: its part per axis.
  void search(int node, const float* q, Candidates& found, float cell_sq, float* offset) const;
};

}  // namespace aloam
