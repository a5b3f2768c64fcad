#include "aloam_nodelet/core/kd_tree.h"

#include <algorithm>
#include <cstdint>

namespace aloam
{
namespace
{
// Points per leaf: small enough to prune well, large enough that the tree stays shallow. With the leaves
// scanned axis by axis, 32 measured best of 8, 16, 24, 32, 48, 64 on KITTI (aloam_kd_tree_bench: the
// odometry and mapping queries, and the builds after the pose); scanned point by point, 16 had been.
constexpr int kLeafSize = 32;
}  // namespace

/// The best candidates so far, nearest first, at most `k` of them, all below the search radius. Kept in
/// the caller's vectors, sized to k up front; finish() cuts them to the count found.
class KdTree::Candidates
{
public:
  Candidates(int k, float max_sq_distance, int skip, std::vector<int>& index, std::vector<float>& sq_distance)
    : k_(k), bound_(max_sq_distance), skip_(skip), index_(index), sq_distance_(sq_distance)
  {
    index_.resize(static_cast<std::size_t>(k));
    sq_distance_.resize(static_cast<std::size_t>(k));
  }

  /// Squared distance a new point must beat.
  float bound() const { return bound_; }

  /// Takes a point whose squared distance beats bound().
  void offer(int index, float sq_distance)
  {
    if (index == skip_)
    {
      return;
    }
    // Insertion keeps the (short) list sorted; a full list drops its farthest.
    int at = size_ < k_ ? size_++ : k_ - 1;
    float* d = sq_distance_.data();
    int* id = index_.data();
    while (at > 0 && d[at - 1] > sq_distance)
    {
      d[at] = d[at - 1];
      id[at] = id[at - 1];
      --at;
    }
    d[at] = sq_distance;
    id[at] = index;
    if (size_ == k_)
    {
      bound_ = d[k_ - 1];
    }
  }

  /// Cuts the caller's vectors to the candidates found; returns their count.
  int finish()
  {
    index_.resize(static_cast<std::size_t>(size_));
    sq_distance_.resize(static_cast<std::size_t>(size_));
    return size_;
  }

private:
  int k_;
  int size_ = 0;
  float bound_;
  int skip_;
  std::vector<int>& index_;
  std::vector<float>& sq_distance_;
};

void KdTree::clear()
{
  entries_.clear();
  nodes_.clear();
  for (auto& axis : coordinates_)
  {
    axis.clear();
  }
}

void KdTree::build(const Cloud& cloud)
{
  build(cloud, 0, static_cast<int>(cloud.size()));
}

void KdTree::build(const Cloud& cloud, int begin, int end)
{
  clear();
  begin = std::max(begin, 0);
  end = std::min(end, static_cast<int>(cloud.size()));
  for (int i = begin; i < end; ++i)
  {
    const Point& p = cloud.points[i];
    if (isFinite(p))
    {
      entries_.push_back(Entry{ { p.x, p.y, p.z }, i });
    }
  }
  if (!entries_.empty())
  {
    Box box;
    for (int a = 0; a < 3; ++a)
    {
      box.lo[a] = box.hi[a] = entries_[0].p[a];
    }
    for (const Entry& e : entries_)
    {
      for (int a = 0; a < 3; ++a)
      {
        box.lo[a] = std::min(box.lo[a], e.p[a]);
        box.hi[a] = std::max(box.hi[a], e.p[a]);
      }
    }
    nodes_.reserve(4 * entries_.size() / kLeafSize + 1);
    buildNode(0, static_cast<int>(entries_.size()), box);
    // The leaves scan the coordinates axis by axis, in tree order.
    for (int a = 0; a < 3; ++a)
    {
      coordinates_[a].resize(entries_.size());
      for (std::size_t i = 0; i < entries_.size(); ++i)
      {
        coordinates_[a][i] = entries_[i].p[a];
      }
    }
  }
}

int KdTree::buildNode(int begin, int end, const Box& box)
{
  const int id = static_cast<int>(nodes_.size());
  nodes_.push_back(Node{ begin, end });
  if (end - begin <= kLeafSize)
  {
    return id;
  }
  // Split the widest side of the node's box at the median. The box is the parent's cut at the split
  // (not the points' tight bounds): choosing the axis needs no pass over the points.
  int axis = 0;
  for (int a = 1; a < 3; ++a)
  {
    if (box.hi[a] - box.lo[a] > box.hi[axis] - box.lo[axis])
    {
      axis = a;
    }
  }
  const int mid = begin + (end - begin) / 2;
  std::nth_element(entries_.begin() + begin, entries_.begin() + mid, entries_.begin() + end,
                   [axis](const Entry& a, const Entry& b) { return a.p[axis] < b.p[axis]; });
  const float split = entries_[mid].p[axis];
  Box left_box = box, right_box = box;
  left_box.hi[axis] = split;
  right_box.lo[axis] = split;
  const int left = buildNode(begin, mid, left_box);
  const int right = buildNode(mid, end, right_box);
  Node& node = nodes_[id];
  node.left = left;
  node.right = right;
  node.axis = axis;
  node.split = split;
  return id;
}

void KdTree::search(int id, const float* q, Candidates& found, float cell_sq, float* offset) const
{
  const Node& node = nodes_[id];
  if (node.left < 0)
  {
    // All distances of the leaf first (a loop the compiler vectorizes), then the few that beat the bound.
    const int n = node.end - node.begin;
    const float* x = coordinates_[0].data() + node.begin;
    const float* y = coordinates_[1].data() + node.begin;
    const float* z = coordinates_[2].data() + node.begin;
    float sq[kLeafSize];
    for (int i = 0; i < n; ++i)
    {
      const float dx = x[i] - q[0], dy = y[i] - q[1], dz = z[i] - q[2];
      sq[i] = dx * dx + dy * dy + dz * dz;
    }
    for (int i = 0; i < n; ++i)
    {
      if (sq[i] < found.bound())
      {
        found.offer(entries_[node.begin + i].index, sq[i]);
      }
    }
    return;
  }
  // Left holds coordinates <= split, right >= split: descend the query's side first, then the other
  // side only if its cell comes closer than the current bound. The far cell's distance follows from
  // this cell's: along the split axis the query is now |diff| outside (offset[] keeps the squared
  // distance per axis), so every point there is at least cell_sq - offset + diff^2 away.
  const float diff = q[node.axis] - node.split;
  const int near_side = diff < 0.0f ? node.left : node.right;
  const int far_side = diff < 0.0f ? node.right : node.left;
  search(near_side, q, found, cell_sq, offset);
  const float old_offset = offset[node.axis];
  const float far_sq = cell_sq - old_offset + diff * diff;
  if (far_sq < found.bound())
  {
    offset[node.axis] = diff * diff;
    search(far_side, q, found, far_sq, offset);
    offset[node.axis] = old_offset;
  }
}

int KdTree::nearest(const Point& query, float max_sq_distance, float* sq_distance, int skip) const
{
  thread_local std::vector<int> index;
  thread_local std::vector<float> distance;
  if (nodes_.empty() || !isFinite(query))
  {
    return -1;
  }
  const float q[3] = { query.x, query.y, query.z };
  Candidates found(1, max_sq_distance, skip, index, distance);
  float offset[3] = { 0.0f, 0.0f, 0.0f };
  search(0, q, found, 0.0f, offset);
  if (found.finish() == 0)
  {
    return -1;
  }
  if (sq_distance != nullptr)
  {
    *sq_distance = distance.front();
  }
  return index.front();
}

int KdTree::nearestK(const Point& query, int k, float max_sq_distance, std::vector<int>& index,
                     std::vector<float>& sq_distance) const
{
  Candidates found(std::max(k, 0), max_sq_distance, -1, index, sq_distance);
  if (k > 0 && !nodes_.empty() && isFinite(query))
  {
    const float q[3] = { query.x, query.y, query.z };
    float offset[3] = { 0.0f, 0.0f, 0.0f };
    search(0, q, found, 0.0f, offset);
  }
  return found.finish();
}

}  // namespace aloam
