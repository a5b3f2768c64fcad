// A static 3-D kd-tree for the exact, radius-bounded neighbour queries of odometry and mapping.
#pragma once

#include <cstddef>
#include <memory>
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
/// Against nanoflann 1.4.3 (Debian's libnanoflann-dev, same leaf size 16, behind -DALOAM_KDTREE_NANOFLANN=ON;
/// issue 13), KITTI 00 0-100, loaded 2-core machine, medians of 7 interleaved runs of aloam_kd_tree_bench:
/// build own/nanoflann 0.69/0.68 ms (odometry edges, 5.2k points), 3.9/4.0 (odometry planes, 29k), 4.3/4.7
/// (map edges, 31k), 1.7/2.2 (map planes, 16k); per query 362/357 ns, 643/422 ns (nearest, 25 m^2), 834/905 ns,
/// 561/801 ns (5 nearest, 2 m^2). End to end (aloam_bench --only kitti, 3+3 interleaved, thread CPU ms,
/// medians) odometry 5.3/5.1, mapping 10.3/9.2, map update 11.4/11.0: within noise (registration, which
/// has no tree, moved 5.3/4.9); poses identical (drift 1.270 %, ATE 0.150 m both). The submap's two builds
/// are about a third of mapping's update (5.9 of 19.6 ms).
class KdTree
{
public:
  /// Indexes every finite point of `cloud`.
  void build(const Cloud& cloud);
  /// Indexes the finite points of `cloud` with index in [begin, end). Query results are cloud indices.
  void build(const Cloud& cloud, int begin, int end);
  void clear();

  /// "own" or "nanoflann" (the measurement variant, see below).
  static const char* implementation();

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
  std::vector<Node> nodes_;

  int buildNode(int begin, int end, const Box& box);
  /// `cell_sq`: squared distance from the query to the node's cell; `offset`: its part per axis.
  void search(int node, const float* q, Candidates& found, float cell_sq, float* offset) const;

  // Measurement variant: kd_tree.cpp compiled with ALOAM_KDTREE_NANOFLANN answers from a nanoflann index
  // (which refers to entries_ by address, hence the heap and the rebuild on copy) instead of nodes_.
  // The layout here is the same either way, so only kd_tree.cpp changes between the two.
public:
  KdTree();
  ~KdTree();
  KdTree(const KdTree& other);
  KdTree(KdTree&& other) noexcept;
  KdTree& operator=(const KdTree& other);
  KdTree& operator=(KdTree&& other) noexcept;

private:
  struct Index;
  struct IndexDeleter
  {
    void operator()(Index* index) const;
  };
  std::unique_ptr<Index, IndexDeleter> index_;
  void rebuildIndex();
};

}  // namespace aloam
