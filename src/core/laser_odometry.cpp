#include "aloam_nodelet/core/laser_odometry.h"

#include <algorithm>
#include <cmath>


#include "aloam_nodelet/core/lidar_factors.h"
#include "aloam_nodelet/core/pose_solver.h"

namespace aloam
{
namespace
{
Eigen::Vector3d vec(const Point& p)
{
  return Eigen::Vector3d(p.x, p.y, p.z);
}

double squaredDistance(const Point& a, const Point& b)
{
  const double dx = a.x - b.x, dy = a.y - b.y, dz = a.z - b.z;
  return dx * dx + dy * dy + dz * dz;
}

// Rings [first, last] clipped to the rings the cloud has, as an index range.
std::pair<int, int> ringSpan(const std::vector<int>& begins, int first, int last)
{
  const int rings = static_cast<int>(begins.size()) - 1;
  first = std::max(first, 0);
  last = std::min(last, rings - 1);
  if (first > last)
  {
    return { 0, 0 };
  }
  return { begins[first], begins[last + 1] };
}
}  // namespace

std::vector<int> ringBegins(const Cloud& cloud)
{
  int max_ring = -1;
  for (const auto& p : cloud.points)
  {
    max_ring = std::max(max_ring, int(p.ring));
  }
  std::vector<int> begins(static_cast<std::size_t>(max_ring + 2), 0);
  // counting: begins[r + 1] = number of points with ring <= r
  for (const auto& p : cloud.points)
  {
    ++begins[p.ring + 1];
  }
  for (std::size_t r = 1; r < begins.size(); ++r)
  {
    begins[r] += begins[r - 1];
  }
  return begins;
}

LaserOdometry::LaserOdometry(LaserOdometryConfig config) : config_(config)
{
}

void LaserOdometry::reset()
{
  pose_ = Pose();
  motion_ = Pose();
  last_corners_.reset();
  last_surfs_.reset();
  last_distorted_ = false;
}

void LaserOdometry::keepAsLast(std::shared_ptr<const Cloud> corners, std::shared_ptr<const Cloud> surfs)
{
  last_corners_ = std::move(corners);
  last_surfs_ = std::move(surfs);
  last_corner_ring_begin_ = ringBegins(*last_corners_);
  last_surf_ring_begin_ = ringBegins(*last_surfs_);
  // An empty cloud cannot be indexed; searches check sizes before using the trees.
  if (!last_corners_->empty())
  {
    corner_tree_.setInputCloud(last_corners_);
  }
  if (!last_surfs_->empty())
  {
    surf_tree_.setInputCloud(last_surfs_);
  }
}

LaserOdometry::Matches LaserOdometry::solve(const Cloud& sharp, const Cloud& flat, Pose& motion) const
{
  Matches total;
  const Cloud& last_c = *last_corners_;
  const Cloud& last_s = *last_surfs_;
  const int nearby = static_cast<int>(std::floor(config_.nearby_scan));

  std::vector<int> index(1);
  std::vector<float> sq_dist(1);
  for (int outer = 0; outer < config_.outer_iterations; ++outer)
  {
    PoseProblem problem(motion, config_.huber_delta);
    Matches m;

    for (const Point& p : sharp.points)
    {
      const Point sel = transformPoint(motion, p);
      if (corner_tree_.nearestKSearch(sel, 1, index, sq_dist) < 1 || sq_dist[0] >= config_.distance_sq_threshold)
      {
        continue;
      }
      const int closest = index[0];
      const int ring = last_c.points[closest].ring;
      // Second point of the line: the nearest one on a neighbouring ring (not the same ring).
      double best = config_.distance_sq_threshold;
      int second = -1;
      for (const auto& [lo, hi] : { ringSpan(last_corner_ring_begin_, ring + 1, ring + nearby),
                                    ringSpan(last_corner_ring_begin_, ring - nearby, ring - 1) })
      {
        for (int j = lo; j < hi; ++j)
        {
          const double d = squaredDistance(last_c.points[j], sel);
          if (d < best)
          {
            best = d;
            second = j;
          }
        }
      }
      if (second < 0)
      {
        continue;
      }
      const Eigen::Vector3d a = vec(last_c.points[closest]);
      const Eigen::Vector3d b = vec(last_c.points[second]);
      const double length = (a - b).norm();
      if (!(length > 1e-6))
      {
        continue;
      }
      problem.addResidual(PointToLineResidual::create(vec(p), a, (a - b) / length));
      ++m.corners;
    }

    for (const Point& p : flat.points)
    {
      const Point sel = transformPoint(motion, p);
      if (surf_tree_.nearestKSearch(sel, 1, index, sq_dist) < 1 || sq_dist[0] >= config_.distance_sq_threshold)
      {
        continue;
      }
      const int closest = index[0];
      const int ring = last_s.points[closest].ring;
      // Plane through the closest point, the nearest other point on the same or a lower ring and the
      // nearest point on a higher ring.
      double best_low = config_.distance_sq_threshold, best_high = config_.distance_sq_threshold;
      int low = -1, high = -1;
      const auto [lo, hi] = ringSpan(last_surf_ring_begin_, ring - nearby, ring);
      for (int j = lo; j < hi; ++j)
      {
        const double d = squaredDistance(last_s.points[j], sel);
        if (j != closest && d < best_low)
        {
          best_low = d;
          low = j;
        }
      }
      const auto [lo2, hi2] = ringSpan(last_surf_ring_begin_, ring + 1, ring + nearby);
      for (int j = lo2; j < hi2; ++j)
      {
        const double d = squaredDistance(last_s.points[j], sel);
        if (d < best_high)
        {
          best_high = d;
          high = j;
        }
      }
      if (low < 0 || high < 0)
      {
        continue;
      }
      const Eigen::Vector3d l = vec(last_s.points[closest]);
      Eigen::Vector3d n = (vec(last_s.points[low]) - l).cross(vec(last_s.points[high]) - l);
      const double norm = n.norm();
      if (!(norm > 1e-9))
      {
        continue;
      }
      n /= norm;
      problem.addResidual(PointToPlaneResidual::create(vec(p), n, -n.dot(l)));
      ++m.planes;
    }

    total = m;
    if (m.corners + m.planes < config_.min_correspondences)
    {
      break;
    }
    problem.solve(config_.max_iterations);
    motion = problem.pose();
    if (outer + 1 == config_.outer_iterations)
    {
      total.constraint = problem.constraintStrength(config_.constraint_lever_arm);
    }
  }
  return total;
}

void deskewToSweepEnd(const Cloud& in, const Pose& motion, double scan_period, Cloud& out)
{
  const double inv_period = scan_period > 0.0 ? 1.0 / scan_period : 0.0;
  const Pose end_from_start = motion.inverse();
  out.header = in.header;
  out.points.clear();
  out.points.reserve(in.size());
  for (const Point& p : in.points)
  {
    const double s = std::clamp(p.time * inv_period, 0.0, 1.0);
    out.points.push_back(transformPoint(end_from_start * motion.interpolated(s), p));
  }
  setUnorganized(out);
}

std::shared_ptr<const Cloud> LaserOdometry::toSweepEnd(const std::shared_ptr<const FeatureSet>& owner,
                                                       const Cloud& cloud, const Pose& motion) const
{
  if (!(config_.deskew && owner->has_time))
  {
    // Aliasing pointer: shares ownership of the feature set, no copy.
    return std::shared_ptr<const Cloud>(owner, &cloud);
  }
  auto out = std::make_shared<Cloud>();
  deskewToSweepEnd(cloud, motion, owner->scan_period, *out);
  return out;
}

OdometryFrame LaserOdometry::process(const std::shared_ptr<const FeatureSet>& features)
{
  OdometryFrame frame;
  frame.stamp = features->stamp;
  const bool motion_unknown = motion_unknown_;
  motion_unknown_ = false;

  if (!initialized())
  {
    frame.status = OdometryStatus::kInitialized;
    frame.distorted = config_.deskew && features->has_time;
  }
  else
  {
    Pose motion = config_.constant_velocity ? motion_ : Pose();
    const Pose prior = motion;
    frame.status = OdometryStatus::kDegraded;
    if (static_cast<int>(last_corners_->size()) >= config_.min_last_corners &&
        static_cast<int>(last_surfs_->size()) >= config_.min_last_surfs)
    {
      // Deskew with the predicted motion, then match as a rigid sweep (as KISS-ICP does). Optimising the
      // deskew together with the motion (LOAM) measured unstable: a velocity error deskews both the sweep
      // and, later, the reference it becomes, and so it persists and grows. Against a still-distorted
      // previous sweep, match distorted to distorted: both carry the same distortion.
      const bool deskew = config_.deskew && features->has_time && !last_distorted_;
      Cloud sharp, flat;
      if (deskew)
      {
        deskewToSweepEnd(features->sharp, prior, features->scan_period, sharp);
        deskewToSweepEnd(features->flat, prior, features->scan_period, flat);
      }
      const Matches m = solve(deskew ? sharp : features->sharp, deskew ? flat : features->flat, motion);
      frame.corner_matches = m.corners;
      frame.plane_matches = m.planes;
      frame.constraint = m.constraint;
      const bool enough = m.corners + m.planes >= config_.min_correspondences &&
                          m.constraint >= config_.min_constraint;
      const bool sane = motion.isFinite() && motion.t.norm() <= config_.max_translation_per_sweep;
      if (enough && sane)
      {
        frame.status = OdometryStatus::kOk;
      }
      else
      {
        motion = prior;
      }
    }
    motion_ = motion;
    pose_ = pose_ * motion;
  }

  frame.pose = pose_;
  frame.motion = motion_;
  // After a gap the solved motion spans the gap, not this sweep: no deskewing with it, no prior from it.
  const Pose sweep_motion = motion_unknown ? Pose() : motion_;
  frame.distorted = frame.distorted || (motion_unknown && config_.deskew && features->has_time);
  frame.corners = toSweepEnd(features, features->less_sharp, sweep_motion);
  frame.surfs = toSweepEnd(features, features->less_flat, sweep_motion);
  frame.full = toSweepEnd(features, features->full, sweep_motion);
  if (motion_unknown)
  {
    motion_ = Pose();
  }
  keepAsLast(frame.corners, frame.surfs);
  last_distorted_ = frame.distorted;
  return frame;
}

}  // namespace aloam
