#include "aloam_nodelet/core/laser_odometry.h"

#include <algorithm>
#include <cmath>

#include "aloam_nodelet/core/pose_solver.h"

namespace aloam
{
namespace
{
Eigen::Vector3d vec(const Point& p)
{
  return Eigen::Vector3d(p.x, p.y, p.z);
}

// Ratios of durations this close to 1 are 1: stamps rounded to nanoseconds, or a spacing equal to the scan
// period, must reproduce the unscaled motion bit for bit (a steady rate behaves as without time scaling).
constexpr double kUnitRatioTolerance = 1e-6;

double timeRatio(double numerator, double denominator)
{
  const double ratio = numerator / denominator;
  return std::fabs(ratio - 1.0) < kUnitRatioTolerance ? 1.0 : ratio;
}

// Rings [first, last] clipped to the rings a cloud has.
std::pair<int, int> clippedRings(const std::vector<KdTree>& ring_trees, int first, int last)
{
  return { std::max(first, 0), std::min(last, static_cast<int>(ring_trees.size()) - 1) };
}

// The point nearest to `query` on rings [first, last], other than `skip`, closer than `max_sq_distance`
// (lowered to the distance of the point found); -1 if none.
int nearestOnRings(const std::vector<KdTree>& ring_trees, const Point& query, int first, int last,
                   float& max_sq_distance, int skip = -1)
{
  const auto [lo, hi] = clippedRings(ring_trees, first, last);
  int best = -1;
  for (int r = lo; r <= hi; ++r)
  {
    float d = 0.0f;
    const int j = ring_trees[r].nearest(query, max_sq_distance, &d, skip);
    if (j >= 0)
    {
      max_sq_distance = d;
      best = j;
    }
  }
  return best;
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

std::vector<RingReach> ringReach(const std::vector<double>& e, double window_deg)
{
  const int n = static_cast<int>(e.size());
  std::vector<RingReach> reach(e.size());
  for (int r = 0; r < n; ++r)
  {
    RingReach& out = reach[static_cast<std::size_t>(r)];
    out.above = r + 1 < n ? 1 : 0;
    while (r + out.above + 1 < n && 0.5 * (e[r + out.above] + e[r + out.above + 1]) - e[r] <= window_deg)
    {
      ++out.above;
    }
    out.below = r > 0 ? 1 : 0;
    while (r - out.below - 1 >= 0 && e[r] - 0.5 * (e[r - out.below] + e[r - out.below - 1]) <= window_deg)
    {
      ++out.below;
    }
  }
  return reach;
}

LaserOdometry::LaserOdometry(LaserOdometryConfig config, std::shared_ptr<Executor> executor)
  : executor_(executor ? std::move(executor) : std::make_shared<Executor>(config.threads))
{
  setConfig(config);
}

void LaserOdometry::setConfig(const LaserOdometryConfig& config)
{
  config_ = config;
  ring_reach_.clear();
  if (config_.nearby_elevation_deg > 0.0)
  {
    ring_reach_ = ringReach(config_.ring_elevations_deg, config_.nearby_elevation_deg);
  }
}

RingReach LaserOdometry::reach(int ring) const
{
  if (ring >= 0 && ring < static_cast<int>(ring_reach_.size()))
  {
    return ring_reach_[static_cast<std::size_t>(ring)];
  }
  const int nearby = static_cast<int>(std::floor(config_.nearby_scan));
  return RingReach{ nearby, nearby };
}

void LaserOdometry::reset()
{
  pose_ = Pose();
  motion_ = Pose();
  last_corners_.reset();
  last_surfs_.reset();
  last_indexed_ = false;
  last_distorted_ = false;
  motion_dt_ = 0.0;
  last_stamp_ = 0.0;
}

void LaserOdometry::indexLast()
{
  if (last_indexed_ || !last_corners_)
  {
    return;
  }
  indexByRing(*last_corners_, corner_tree_, corner_ring_trees_);
  indexByRing(*last_surfs_, surf_tree_, surf_ring_trees_);
  last_indexed_ = true;
}

void LaserOdometry::indexByRing(const Cloud& cloud, KdTree& all, std::vector<KdTree>& rings)
{
  all.build(cloud);
  const std::vector<int> begins = ringBegins(cloud);
  rings.resize(begins.size() - 1);
  for (std::size_t r = 0; r + 1 < begins.size(); ++r)
  {
    rings[r].build(cloud, begins[r], begins[r + 1]);
  }
}

bool LaserOdometry::matchEdge(const Point& p, const Pose& motion, double search_scale, LineMatch& match) const
{
  const Cloud& last = *last_corners_;
  const auto threshold = static_cast<float>(config_.distance_sq_threshold * search_scale);
  const Point sel = transformPoint(motion, p);
  const int closest = corner_tree_.nearest(sel, threshold);
  if (closest < 0)
  {
    return false;
  }
  const int ring = last.points[closest].ring;
  const RingReach nearby = reach(ring);
  // Second point of the line: the nearest one on a neighbouring ring (not the same ring).
  float best = threshold;
  const int above = nearestOnRings(corner_ring_trees_, sel, ring + 1, ring + nearby.above, best);
  const int below = nearestOnRings(corner_ring_trees_, sel, ring - nearby.below, ring - 1, best);
  const int second = below >= 0 ? below : above;
  if (second < 0)
  {
    return false;
  }
  const Eigen::Vector3d a = vec(last.points[closest]);
  const Eigen::Vector3d b = vec(last.points[second]);
  const double length = (a - b).norm();
  if (!(length > 1e-6))
  {
    return false;
  }
  match = LineMatch{ vec(p), a, (a - b) / length };
  return true;
}

bool LaserOdometry::matchPlane(const Point& p, const Pose& motion, double search_scale, PlaneMatch& match) const
{
  const Cloud& last = *last_surfs_;
  const auto threshold = static_cast<float>(config_.distance_sq_threshold * search_scale);
  const Point sel = transformPoint(motion, p);
  const int closest = surf_tree_.nearest(sel, threshold);
  if (closest < 0)
  {
    return false;
  }
  const int ring = last.points[closest].ring;
  const RingReach nearby = reach(ring);
  // Plane through the closest point, the nearest other point on the same or a lower ring and the
  // nearest point on a higher ring.
  float low_bound = threshold, high_bound = threshold;
  const int low = nearestOnRings(surf_ring_trees_, sel, ring - nearby.below, ring, low_bound, closest);
  const int high = nearestOnRings(surf_ring_trees_, sel, ring + 1, ring + nearby.above, high_bound);
  if (low < 0 || high < 0)
  {
    return false;
  }
  const Eigen::Vector3d l = vec(last.points[closest]);
  Eigen::Vector3d n = (vec(last.points[low]) - l).cross(vec(last.points[high]) - l);
  const double norm = n.norm();
  if (!(norm > 1e-9))
  {
    return false;
  }
  n /= norm;
  match = PlaneMatch{ vec(p), n, -n.dot(l) };
  return true;
}

LaserOdometry::Matches LaserOdometry::solve(const Cloud& sharp, const Cloud& flat, Pose& motion, int outer_iterations,
                                            double search_scale) const
{
  MatchSolveOptions options = matchSolveOptionsOf(config_);
  options.executor = executor_.get();
  options.outer_iterations = outer_iterations;
  options.first_search_scale = search_scale;
  const MatchSolveResult r = matchAndSolve(
      motion, sharp.size(), flat.size(), options,
      [&](int i, const Pose& m, double scale, LineMatch& slot) { return matchEdge(sharp.points[i], m, scale, slot); },
      [&](int i, const Pose& m, double scale, PlaneMatch& slot) { return matchPlane(flat.points[i], m, scale, slot); });
  return Matches{ r.lines, r.planes, r.constraint, r.degenerate, r.remapped, r.inlier_share };
}

std::vector<Pose> LaserOdometry::hypotheses(const Pose& prior) const
{
  std::vector<Pose> starts;
  starts.push_back(prior);  // first: the prediction again, with the wider first search and more iterations
  // Near-zero prediction: zero and the doubled prediction would repeat it.
  constexpr double kTrivialTranslation = 0.01, kTrivialAngle = 1e-3;
  const bool trivial = prior.t.norm() < kTrivialTranslation && Eigen::AngleAxisd(prior.q).angle() < kTrivialAngle;
  if (!trivial)
  {
    starts.push_back(Pose());             // a stop
    starts.push_back(prior.scaled(2.0));  // a start, an acceleration
  }
  else if (config_.hypothesis_translation > 0.0)
  {
    // From rest (or after a gap) nothing predicts the direction: translations along the sensor's x and y
    // axes, at the step and twice the step.
    for (const double d : { config_.hypothesis_translation, 2.0 * config_.hypothesis_translation })
    {
      const Eigen::Vector3d axes[] = { Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY() };
      for (const Eigen::Vector3d& axis : axes)
      {
        starts.emplace_back(prior.q, prior.t + d * axis);
        starts.emplace_back(prior.q, prior.t - d * axis);
      }
    }
  }
  const double yaw = config_.hypothesis_yaw_deg * M_PI / 180.0;
  for (const double angle : { yaw, -yaw, 2.0 * yaw, -2.0 * yaw })
  {
    // Turned about the sensor's z axis at the sweep end (motion = previous end <- this end).
    Pose turned = prior;
    turned.q = (prior.q * Eigen::Quaterniond(Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitZ()))).normalized();
    starts.push_back(turned);
  }
  return starts;
}

Pose LaserOdometry::predict(double dt) const
{
  if (!config_.constant_velocity)
  {
    return Pose();
  }
  if (!config_.time_scaling || !(dt > 0.0) || !(motion_dt_ > 0.0))
  {
    return motion_;
  }
  return motion_.scaled(timeRatio(dt, motion_dt_));
}

Pose LaserOdometry::perScanPeriod(const Pose& motion, double dt, double scan_period) const
{
  if (!config_.time_scaling || !(dt > 0.0) || !(scan_period > 0.0))
  {
    return motion;
  }
  return motion.scaled(timeRatio(scan_period, dt));
}

Pose sweepEndFromPointTime(const Pose& motion, double s)
{
  return motion.inverse() * motion.interpolated(s);
}

void deskewToSweepEnd(const Cloud& in, const Pose& motion, double scan_period, Cloud& out)
{
  const double inv_period = scan_period > 0.0 ? 1.0 / scan_period : 0.0;
  // sweepEndFromPointTime per point: the pose at fraction s of the sweep is a rotation by s * angle about
  // the motion's fixed axis and a translation s * t (slerp from the identity, at constant velocity), so
  // one sincos per point instead of a general slerp.
  const Eigen::AngleAxisd rotation(motion.q.normalized());
  const double half_angle = 0.5 * rotation.angle();
  const Eigen::Vector3d axis = rotation.axis();
  const Pose end_from_start = motion.inverse();
  const Eigen::Matrix3d end_rotation = end_from_start.q.toRotationMatrix();
  out.header = in.header;
  out.points.clear();
  out.points.reserve(in.size());
  for (const Point& p : in.points)
  {
    const double s = std::clamp(p.time * inv_period, 0.0, 1.0);
    const double sin_half = std::sin(s * half_angle);
    const Eigen::Quaterniond q_s(std::cos(s * half_angle), sin_half * axis.x(), sin_half * axis.y(),
                                 sin_half * axis.z());
    const Eigen::Vector3d at_start = q_s * Eigen::Vector3d(p.x, p.y, p.z) + s * motion.t;
    const Eigen::Vector3d at_end = end_rotation * at_start + end_from_start.t;
    Point q = p;
    q.x = static_cast<float>(at_end.x());
    q.y = static_cast<float>(at_end.y());
    q.z = static_cast<float>(at_end.z());
    out.points.push_back(q);
  }
  setUnorganized(out);
}

std::shared_ptr<const Cloud> fullAtSweepEnd(const OdometryFrame& frame)
{
  if (!frame.full || frame.full_motion.isIdentity())
  {
    return frame.full;
  }
  auto out = std::make_shared<Cloud>();
  deskewToSweepEnd(*frame.full, frame.full_motion, frame.scan_period, *out);
  return out;
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
  OdometryFrame frame = track(features);
  indexLast();
  return frame;
}

OdometryFrame LaserOdometry::track(const std::shared_ptr<const FeatureSet>& features)
{
  indexLast();  // in case the caller skipped it after the previous sweep
  OdometryFrame frame;
  frame.stamp = features->stamp;
  const bool motion_unknown = motion_unknown_;
  motion_unknown_ = false;
  // Seconds since the previous sweep; 0 when unknown (first sweep, repeated or earlier stamp).
  const double dt = initialized() ? std::max(features->stamp - last_stamp_, 0.0) : 0.0;
  frame.dt = dt;
  frame.scan_period = features->scan_period;

  if (!initialized())
  {
    frame.status = OdometryStatus::kInitialized;
    frame.distorted = config_.deskew && features->has_time;
  }
  else
  {
    Pose motion = predict(dt);
    const Pose prior = motion;
    frame.status = OdometryStatus::kDegraded;
    if (static_cast<int>(last_corners_->size()) >= config_.min_last_corners &&
        static_cast<int>(last_surfs_->size()) >= config_.min_last_surfs)
    {
      // Deskew with the predicted motion, then match as a rigid sweep (as KISS-ICP does). Optimising the
      // deskew together with the motion (LOAM) measured unstable: a velocity error deskews both the sweep
      // and, later, the reference it becomes, and so it persists and grows. Against a still-distorted
      // previous sweep, match distorted to distorted: both carry the same distortion. The sensor moves
      // by velocity x scan_period within the sweep, not by the whole stamp-to-stamp motion.
      const bool deskew = config_.deskew && features->has_time && !last_distorted_;
      Cloud sharp, flat;
      if (deskew)
      {
        const Pose within = perScanPeriod(prior, dt, features->scan_period);
        deskewToSweepEnd(features->sharp, within, features->scan_period, sharp);
        deskewToSweepEnd(features->flat, within, features->scan_period, flat);
      }
      const Cloud& sharp_in = deskew ? sharp : features->sharp;
      const Cloud& flat_in = deskew ? flat : features->flat;
      Matches m = solve(sharp_in, flat_in, motion, config_.outer_iterations, 1.0);
      const auto usable = [&](const Matches& r, const Pose& solved)
      {
        return r.corners + r.planes >= config_.min_correspondences && solved.isFinite() &&
               solved.t.norm() <= config_.max_translation_per_sweep;
      };
      if (config_.motion_hypotheses && m.inlier_share < config_.hypothesis_min_inlier_share)
      {
        // The prediction looks wrong: solve from other starts, keep the one with the most inliers.
        frame.hypotheses_tried = true;
        const std::vector<Pose> starts = hypotheses(prior);
        for (std::size_t h = 0; h < starts.size(); ++h)
        {
          Pose candidate = starts[h];
          const Matches c =
              solve(sharp_in, flat_in, candidate, config_.hypothesis_outer_iterations, config_.hypothesis_search_scale);
          // Along a degenerate direction a solve keeps its start, which for these starts is a guess, and a
          // wider search on a poorly constrained sweep wanders: only fully constrained solves count.
          // The prediction's own solve is kept unless another start clearly beats it (by hypothesis_min_gain):
          // on ground alone a shifted start finds about as many inliers as the right one.
          const double to_beat = m.inlier_share + (frame.hypothesis == 0 ? config_.hypothesis_min_gain : 0.0);
          if (usable(c, candidate) && c.degenerate.empty() && (c.inlier_share > to_beat || !usable(m, motion)))
          {
            m = c;
            motion = candidate;
            frame.hypothesis = static_cast<int>(h) + 1;
          }
        }
      }
      frame.inlier_share = m.inlier_share;
      frame.corner_matches = m.corners;
      frame.plane_matches = m.planes;
      frame.constraint = m.constraint;
      frame.degenerate = m.degenerate;
      const bool enough = m.corners + m.planes >= config_.min_correspondences;
      const bool strong = m.constraint >= config_.min_constraint;
      const bool sane = motion.isFinite() && motion.t.norm() <= config_.max_translation_per_sweep;
      if (enough && strong && sane)
      {
        frame.status = OdometryStatus::kOk;
      }
      else if (enough && sane && m.remapped)
      {
        frame.status = OdometryStatus::kRemapped;  // the solve already kept the prior along the weak directions
      }
      else
      {
        motion = prior;
      }
    }
    motion_ = motion;
    motion_dt_ = dt;
    pose_ = pose_ * motion;
  }

  frame.pose = pose_;
  frame.motion = motion_;
  // After a gap the solved motion spans the gap, not this sweep: no deskewing with it, no prior from it.
  const Pose sweep_motion = motion_unknown ? Pose() : perScanPeriod(motion_, dt, features->scan_period);
  frame.distorted = frame.distorted || (motion_unknown && config_.deskew && features->has_time);
  // Mapping's edges are those that bend across the ring; odometry keeps all of LOAM's as its next targets.
  const auto all_corners = toSweepEnd(features, features->less_sharp, sweep_motion);
  frame.corners = features->bending ? toSweepEnd(features, *features->bending, sweep_motion) : all_corners;
  frame.surfs = toSweepEnd(features, features->less_flat, sweep_motion);
  frame.full = std::shared_ptr<const Cloud>(features, &features->full);  // deskewed by whoever displays it
  frame.full_motion = config_.deskew && features->has_time ? sweep_motion : Pose();
  if (motion_unknown)
  {
    motion_ = Pose();
  }
  last_stamp_ = features->stamp;
  last_corners_ = all_corners;
  last_surfs_ = frame.surfs;
  last_indexed_ = false;
  last_distorted_ = frame.distorted;
  return frame;
}

}  // namespace aloam
