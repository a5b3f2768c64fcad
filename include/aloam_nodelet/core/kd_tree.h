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
/// Leaves keep their coordinates axis by axis (the distance loop vectorizes) and hold 32 points. The tree
/// is our own rather than nanoflann: nanoflann has no package on Noetic's Ubuntu 20.04, and ours measured
/// faster on the mapping queries, the most numerous on the pose path. Figures: docs/performance.md#kd-tree.
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
