#include "aloam_nodelet/core/kd_tree.h"

#include <algorithm>
#include <cstdint>

namespace aloam
{
namespace
{
// Points per leaf: small enough to prune well, large enough that the tree stays shallow (16 measured
// best of 4, 8, 12, 16, 24, 32 on KITTI: odometry and mapping queries and the builds after the pose).
constexpr int kLeafSize = 16;

float squaredDistance(const float* a, const float* b)
{
  const float dx = a[0] - b[0], dy = a[1] - b[1], dz = a[2] - b[2];
  return dx * dx + dy * dy + dz * dz;
}
}  // namespace

/// The best candidates so far, nearest first, at most `k` of them, all below the search radius.
class KdTree::Candidates
{
public:
  Candidates(int k, float max_sq_distance, int skip, std::vector<int>& index, std::vector<float>& sq_distance)
    : k_(k), bound_(max_sq_distance), skip_(skip), index_(index), sq_distance_(sq_distance)
  {
    index_.clear();
    sq_distance_.clear();
  }

  /// Squared distance a new point must beat.
  float bound() const { return bound_; }

  void offer(int index, float sq_distance)
  {
    if (!(sq_distance < bound_) || index == skip_)
    {
      return;
    }
    if (static_cast<int>(index_.size()) == k_)
    {
      index_.pop_back();
      sq_distance_.pop_back();
    }
    // Insertion keeps the (short) list sorted.
    const auto at = std::upper_bound(sq_distance_.begin(), sq_distance_.end(), sq_distance);
    const auto offset = at - sq_distance_.begin();
    sq_distance_.insert(at, sq_distance);
    index_.insert(index_.begin() + offset, index);
    if (static_cast<int>(index_.size()) == k_)
    {
      bound_ = sq_distance_.back();
    }
  }

private:
  int k_;
  float bound_;
  int skip_;
  std::vector<int>& index_;
  std::vector<float>& sq_distance_;
};

void KdTree::clear()
{
  entries_.clear();
  nodes_.clear();
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
    for (int i = node.begin; i < node.end; ++i)
    {
      found.offer(entries_[i].index, squaredDistance(entries_[i].p, q));
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
  if (index.empty())
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
  return static_cast<int>(index.size());
}

}  // namespace aloam
