#include "aloam_nodelet/core/laser_mapping.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include <Eigen/Eigenvalues>

#include "aloam_nodelet/core/pose_solver.h"
#include "aloam_nodelet/core/sweep_span.h"
#include "aloam_nodelet/core/voxel_filter.h"

namespace aloam
{
namespace
{
Eigen::Vector3d vec(const Point& p)
{
  return Eigen::Vector3d(p.x, p.y, p.z);
}

// A span solve whose end moved or turned farther than these from the rigid solve's ran off (m, rad).
constexpr double kMaxSpanShift = 1.0;
constexpr double kMaxSpanTurn = 10.0 * M_PI / 180.0;
// Points per chunk of the span solve's correspondence search.
constexpr int kMinChunk = 256;

// Centroid and scatter matrix of the points `index` selects.
void centroidAndScatter(const Cloud& cloud, const std::vector<int>& index, Eigen::Vector3d& centroid,
                        Eigen::Matrix3d& scatter)
{
  centroid.setZero();
  for (const int i : index)
  {
    centroid += vec(cloud.points[i]);
  }
  centroid /= static_cast<double>(index.size());
  scatter.setZero();
  for (const int i : index)
  {
    const Eigen::Vector3d d = vec(cloud.points[i]) - centroid;
    scatter += d * d.transpose();
  }
}

// Moves a sweep's clouds (sensor frame; null: none) by `pose` into `map`, which merges them into its voxels.
void insertSweep(CubeMap& map, const Cloud* corners, const Cloud* surfs, const Pose& pose)
{
  Cloud world;
  for (const Cloud* cloud : { corners, surfs })
  {
    if (!cloud)
    {
      continue;
    }
    world.clear();
    world.points.reserve(cloud->size());
    for (const Point& p : cloud->points)
    {
      world.points.push_back(transformPoint(pose, p));
    }
    cloud == corners ? map.insertCorners(world) : map.insertSurfs(world);
  }
}

// For an edge point `p` (sensor frame) matched to a line of unit direction `u` (map frame) at `pose`: the
// direction across the rings perpendicular to the line (map frame) when the configuration leaves it free
// (LaserMappingConfig::line_ring_crossing_deg), else zero. The cone's normal at p points to higher elevations.
Eigen::Vector3d acrossRings(const Point& p, const Pose& pose, const Eigen::Vector3d& u,
                            const LaserMappingConfig& config)
{
  const double horizontal = std::hypot(double(p.x), double(p.y));
  const double range = std::hypot(horizontal, double(p.z));
  if (!(config.line_ring_crossing_deg > 0.0) || !(horizontal > 0.0) || range < config.line_ring_crossing_min_range)
  {
    return Eigen::Vector3d::Zero();
  }
  const double sin_elevation = p.z / range;
  const Eigen::Vector3d cone_normal(-sin_elevation * p.x / horizontal, -sin_elevation * p.y / horizontal,
                                    horizontal / range);
  const Eigen::Vector3d line = pose.q.conjugate() * u;  // sensor frame
  const double along = cone_normal.dot(line);
  if (std::fabs(along) >= std::sin(config.line_ring_crossing_deg * M_PI / 180.0))
  {
    return Eigen::Vector3d::Zero();
  }
  // |along| < 1, so the part of the cone normal perpendicular to the line is not zero.
  return pose.q * (cone_normal - along * line).normalized();
}

// The leaf scale for a sweep whose plane points (sensor frame) lie at these ranges: a power of two near
// median range / reference, within [min_scale, 1]. `current` holds until the wanted scale is more than
// 0.65 of a power of two away from it (a margin of 0.15 past the midpoint).
double sceneLeafScale(const Cloud& surfs, double reference_range, double min_scale, double current)
{
  constexpr std::size_t kMinPoints = 50;  // fewer: too few to judge the scene by
  if (!(min_scale < 1.0) || !(reference_range > 0.0))
  {
    return 1.0;
  }
  std::vector<float> squared;
  squared.reserve(surfs.size());
  for (const Point& p : surfs.points)
  {
    const float r2 = p.x * p.x + p.y * p.y + p.z * p.z;
    if (std::isfinite(r2))
    {
      squared.push_back(r2);
    }
  }
  if (squared.size() < kMinPoints)
  {
    return current;
  }
  const auto middle = squared.begin() + static_cast<std::ptrdiff_t>(squared.size() / 2);
  std::nth_element(squared.begin(), middle, squared.end());
  const double finest = std::ceil(std::log2(min_scale) - 1e-9);
  const double wanted =
      std::log2(std::clamp(std::sqrt(static_cast<double>(*middle)) / reference_range, min_scale, 1.0));
  const double level = std::log2(current);
  if (std::abs(wanted - level) <= 0.65)
  {
    return current;
  }
  return std::exp2(std::clamp(std::round(wanted), finest, 0.0));
}
}  // namespace

LaserMapping::LaserMapping(LaserMappingConfig config, std::shared_ptr<Executor> executor)
  : config_(config)
  , executor_(executor ? std::move(executor) : std::make_shared<Executor>(config.threads))
  , map_(config.cube_size, config.corner_leaf_size, config.surf_leaf_size)
{
}

void LaserMapping::setConfig(const LaserMappingConfig& config)
{
  config_ = config;
  if (!(config_.leaf_min_scale < 1.0) || leaf_scale_ < config_.leaf_min_scale)
  {
    leaf_scale_ = 1.0;
  }
  submap_ready_ = false;
  map_.setCubeSize(config.cube_size);
  map_.setLeafSizes(cornerLeaf(), surfLeaf());
}

void LaserMapping::reset()
{
  map_.clear();
  leaf_scale_ = 1.0;
  map_.setLeafSizes(cornerLeaf(), surfLeaf());
  submap_ready_ = false;
  pending_insert_ = false;
  held_first_.reset();
  pending_first_ = false;
  correction_ = Pose();
  last_motion_ = Pose();
  last_motion_known_ = false;
  evicted_total_ = 0;
  run_started_ = false;
  continued_ = false;
}

template <typename Search>
bool LaserMapping::recall(SearchMemo* memo, const Point& query, Search&& search)
{
  if (memo == nullptr)
  {
    return search();
  }
  const float dx = query.x - memo->query[0], dy = query.y - memo->query[1], dz = query.z - memo->query[2];
  if (memo->slack > 0.0f && 4.0f * (dx * dx + dy * dy + dz * dz) < memo->slack * memo->slack)
  {
    ++memo->reused;
    return memo->matched;  // the caller's slot still holds that match
  }
  memo->query[0] = query.x;
  memo->query[1] = query.y;
  memo->query[2] = query.z;
  memo->slack = -1.0f;  // until the search records it
  memo->matched = search();
  return memo->matched;
}

bool LaserMapping::fitNeighbours(const KdTree& tree, const Cloud& cloud, const Point& query, int k,
                                 double max_sq_distance, Neighbourhood& fit, SearchMemo* memo)
{
  thread_local std::vector<float> sq_dist;
  // With a memo one more neighbour: the first k are the k nearest either way, the next one gives the slack.
  const int found =
      tree.nearestK(query, memo != nullptr ? k + 1 : k, static_cast<float>(max_sq_distance), fit.index, sq_dist);
  if (found < k)
  {
    return false;
  }
  if (memo != nullptr)
  {
    // Distances in floats of map coordinates (up to a few km): 1 mm covers their rounding many times.
    constexpr float kMargin = 1e-3f;
    const float next = found > k ? std::sqrt(sq_dist[k]) : std::sqrt(static_cast<float>(max_sq_distance));
    memo->slack = next - std::sqrt(sq_dist[k - 1]) - kMargin;
    fit.index.resize(static_cast<std::size_t>(k));
  }
  Eigen::Matrix3d scatter;
  centroidAndScatter(cloud, fit.index, fit.centroid, scatter);
  // Closed-form 3x3 eigen-decomposition: several times faster than the iterative one, and as exact on
  // these well-scaled scatter matrices. Eigenvalues ascend.
  fit.eigen.computeDirect(scatter);
  return true;
}

bool LaserMapping::matchEdge(const Point& p, const Pose& pose, LineMatch& match, SearchMemo* memo) const
{
  const Point query = transformPoint(pose, p);
  const bool found = recall(memo, query,
                            [&]
                            {
                              thread_local Neighbourhood fit;
                              if (!fitNeighbours(corner_tree_, submap_corners_, query, config_.line_neighbours,
                                                 config_.line_max_sq_distance, fit, memo))
                              {
                                return false;
                              }
                              // A line has one dominant direction.
                              const Eigen::Vector3d& lambda = fit.eigen.eigenvalues();
                              if (!(lambda[2] > config_.line_eigen_ratio * lambda[1]))
                              {
                                return false;
                              }
                              match = LineMatch{ vec(p), fit.centroid, fit.eigen.eigenvectors().col(2) };
                              return true;
                            });
  if (found)
  {
    // Outside the memo: the axis depends on the pose, which moves between searches.
    match.free_axis = acrossRings(p, pose, match.direction, config_);
  }
  return found;
}

bool LaserMapping::matchPlane(const Point& p, const Pose& pose, PlaneMatch& match, SearchMemo* memo) const
{
  const Point query = transformPoint(pose, p);
  return recall(memo, query,
                [&]
                {
                  thread_local Neighbourhood fit;
                  if (!fitNeighbours(surf_tree_, submap_surfs_, query, config_.plane_neighbours,
                                     config_.plane_max_sq_distance, fit, memo))
                  {
                    return false;
                  }
                  // The neighbours must spread in two directions: points along one scan line fit every
                  // plane through that line, and their "normal" may tilt freely about it.
                  const Eigen::Vector3d& lambda = fit.eigen.eigenvalues();
                  if (!(lambda[1] > config_.plane_min_spread_ratio * lambda[2]))
                  {
                    return false;
                  }
                  // The normal is the direction of least spread; PCA works for planes through the origin too.
                  const Eigen::Vector3d n = fit.eigen.eigenvectors().col(0);
                  const double d = -n.dot(fit.centroid);
                  for (const int i : fit.index)
                  {
                    if (std::fabs(n.dot(vec(submap_surfs_.points[i])) + d) > config_.plane_max_distance)
                    {
                      return false;
                    }
                  }
                  match = PlaneMatch{ vec(p), n, d };
                  return true;
                });
}

MatchSolveResult LaserMapping::solve(Pose& pose, int outer_iterations, MappingResult& result)
{
  MatchSolveOptions options = matchSolveOptionsOf(config_);
  options.executor = executor_.get();
  options.outer_iterations = outer_iterations;
  const bool reuse = config_.reuse_searches;
  corner_memo_.assign(reuse ? corner_stack_.size() : 0, SearchMemo());
  surf_memo_.assign(reuse ? surf_stack_.size() : 0, SearchMemo());
  const MatchSolveResult r = matchAndSolve(
      pose, corner_stack_.size(), surf_stack_.size(), options,
      [&](int i, const Pose& at, double, LineMatch& slot)
      { return matchEdge(corner_stack_.points[i], at, slot, reuse ? &corner_memo_[i] : nullptr); },
      [&](int i, const Pose& at, double, PlaneMatch& slot)
      { return matchPlane(surf_stack_.points[i], at, slot, reuse ? &surf_memo_[i] : nullptr); });
  for (const auto* memos : { &corner_memo_, &surf_memo_ })
  {
    for (const SearchMemo& memo : *memos)
    {
      result.reused_searches += memo.reused;
    }
  }
  result.corner_matches = r.lines;
  result.plane_matches = r.planes;
  result.constraint = r.constraint;
  result.degenerate = r.degenerate;
  return r;
}

void LaserMapping::insert(const Pose& pose)
{
  insertSweep(map_, &corner_stack_, &surf_stack_, pose);
}

void LaserMapping::releaseHeldFirst(const OdometryFrame& frame)
{
  const HeldSweep held = *held_first_;
  held_first_.reset();
  const double dt = frame.stamp - held.stamp;
  if (!(dt > 0.0) || frame.status == OdometryStatus::kInitialized)
  {
    return;  // no motion to deskew with: the sweep stays out of the map
  }
  // The held sweep lasted as long as its latest point time; the next sweep's motion spans dt.
  double sweep = 0.0;
  for (const auto& cloud : { held.corners, held.surfs })
  {
    if (cloud)
    {
      for (const Point& p : cloud->points)
      {
        sweep = std::max(sweep, static_cast<double>(p.time));
      }
    }
  }
  const Pose within = frame.motion.scaled(sweep / dt);
  Cloud deskewed;
  for (const bool is_corners : { true, false })
  {
    const auto& in = is_corners ? held.corners : held.surfs;
    Cloud& out = is_corners ? first_corners_ : first_surfs_;
    out.clear();
    if (!in)
    {
      continue;
    }
    if (sweep > 0.0)
    {
      deskewToSweepEnd(*in, within, sweep, deskewed);
    }
    voxelDownsample(sweep > 0.0 ? deskewed : *in, is_corners ? cornerLeaf() : surfLeaf(), out);
  }
  first_pose_ = held.pose;
  pending_first_ = true;
}

bool LaserMapping::motionChanged(const OdometryFrame& frame) const
{
  if (!last_motion_known_)
  {
    return false;  // the first motion after a start: nothing to compare it with
  }
  const Pose change = last_motion_.inverse() * frame.motion;
  return Eigen::AngleAxisd(change.q).angle() > config_.span_motion_change_deg * M_PI / 180.0 ||
         change.t.norm() > config_.span_motion_change_m;
}

bool LaserMapping::solveSpan(const OdometryFrame& frame, const Pose& prediction, Pose& pose)
{
  const Pose& used = frame.full_motion;  // sweep start <- end, as odometry deskewed the clouds
  const double period = frame.scan_period;
  if (used.isIdentity() || !(period > 0.0) || !(frame.dt > 0.0) || frame.status == OdometryStatus::kInitialized)
  {
    return false;  // not deskewed
  }
  // Each point back where the sensor was when it took it, and when that was (fraction of the sweep).
  std::vector<Point> points;
  std::vector<double> fraction;
  points.reserve(corner_stack_.size() + surf_stack_.size());
  for (const Cloud* stack : { &corner_stack_, &surf_stack_ })
  {
    for (const Point& p : stack->points)
    {
      const double s = std::clamp(p.time / period, 0.0, 1.0);
      points.push_back(transformPoint(sweepEndFromPointTime(used, s).inverse(), p));
      fraction.push_back(s);
    }
  }
  const int corners = static_cast<int>(corner_stack_.size());
  const int total = static_cast<int>(points.size());

  // Where the sweep started: a sweep's time before the end on the way from the previous sweep's end to the
  // solved end. That is the previous end itself unless sweeps were dropped between them (a throttled topic).
  const Pose previous_end = prediction * frame.motion.inverse();
  const double share = std::min(1.0, period / frame.dt);  // the sweep's part of the stamp-to-stamp motion
  const Pose start_prior = previous_end * (previous_end.inverse() * pose).scaled(1.0 - share);
  SweepSpan span{ start_prior, pose };
  SweepSpanOptions options;
  options.max_iterations = config_.max_iterations;
  options.huber_delta = config_.huber_delta;
  options.start_weight = config_.span_start_weight;
  options.lever_arm = config_.constraint_lever_arm;
  std::vector<SpanLineMatch> line_slots(corners);
  std::vector<SpanPlaneMatch> plane_slots(total - corners);
  std::vector<char> found(total);
  std::vector<SpanLineMatch> lines;
  std::vector<SpanPlaneMatch> planes;
  for (int round = 0; round < config_.span_iterations; ++round)
  {
    executor_->parallelChunks(total, config_.threads, kMinChunk,
                              [&](int begin, int end, int)
                              {
                                for (int i = begin; i < end; ++i)
                                {
                                  const Pose at = span.at(fraction[i]);
                                  found[i] = i < corners ? matchEdge(points[i], at, line_slots[i].match)
                                                         : matchPlane(points[i], at, plane_slots[i - corners].match);
                                }
                              });
    lines.clear();
    planes.clear();
    for (int i = 0; i < total; ++i)
    {
      if (found[i] && i < corners)
      {
        lines.push_back(line_slots[i]);
        lines.back().s = fraction[i];
      }
      else if (found[i])
      {
        planes.push_back(plane_slots[i - corners]);
        planes.back().s = fraction[i];
      }
    }
    if (static_cast<int>(lines.size() + planes.size()) < config_.min_correspondences ||
        !solveSweepSpan(span, lines, planes, start_prior, options))
    {
      return false;
    }
  }
  if ((span.end.t - pose.t).norm() > kMaxSpanShift || span.end.q.angularDistance(pose.q) > kMaxSpanTurn)
  {
    return false;  // a solve that ran off: keep the rigid one
  }
  pose = span.end;
  // The clouds as the span places them, for the map.
  const Pose end_inverse = span.end.inverse();
  for (int i = 0; i < total; ++i)
  {
    Point& p = i < corners ? corner_stack_.points[i] : surf_stack_.points[i - corners];
    p = transformPoint(end_inverse * span.at(fraction[i]), points[i]);
  }
  return true;
}

MappingResult LaserMapping::process(const OdometryFrame& frame)
{
  MappingResult result = registerFrame(frame);
  updateMap(result);
  return result;
}

void LaserMapping::prepareSubmap(const CubeIndex& centre)
{
  submap_corners_.clear();
  submap_surfs_.clear();
  map_.gather(centre, config_.submap_half_xy, config_.submap_half_z, submap_corners_, submap_surfs_);
  corner_tree_.build(submap_corners_);
  surf_tree_.build(submap_surfs_);
  submap_centre_ = centre;
  submap_ready_ = true;
}

MappingResult LaserMapping::registerFrame(const OdometryFrame& frame)
{
  MappingResult result;
  result.stamp = frame.stamp;
  if (!frozen_ && frame.surfs)
  {
    // The map follows in updateMap(), off the pose path.
    leaf_scale_ = sceneLeafScale(*frame.surfs, config_.leaf_reference_range, config_.leaf_min_scale, leaf_scale_);
  }
  result.leaf_scale = leaf_scale_;
  const Pose prediction = correction_ * frame.pose;
  Pose pose = prediction;

  corner_stack_.clear();
  surf_stack_.clear();
  // The two downsamplings are independent: one thread each.
  executor_->parallelChunks(2, config_.threads, 1,
                            [&](int begin, int end, int)
                            {
                              for (int layer = begin; layer < end; ++layer)
                              {
                                const auto& in = layer == 0 ? frame.corners : frame.surfs;
                                if (in)
                                {
                                  voxelDownsample(*in, layer == 0 ? cornerLeaf() : surfLeaf(),
                                                  layer == 0 ? corner_stack_ : surf_stack_);
                                }
                              }
                            });

  // updateMap() prepared the submap around the previous pose; it serves unless the robot changed cube.
  const CubeIndex centre = map_.indexOf(pose.t);
  if (!submap_ready_ || centre != submap_centre_)
  {
    prepareSubmap(centre);
  }
  // Over a loaded map (startIn), a distorted first sweep keeps the prediction and stays out of the map:
  // undeskewed, it would bias its own pose and blur the map; the next sweep registers.
  const bool skip_first = frame.distorted && continued_ && !run_started_;
  if (!skip_first && static_cast<int>(submap_corners_.size()) >= config_.min_map_corners &&
      static_cast<int>(submap_surfs_.size()) >= config_.min_map_surfs)
  {
    const bool hard = frame.hard() && frame.status != OdometryStatus::kInitialized;
    const int outer =
        hard ? std::max(config_.outer_iterations, config_.hard_frame_outer_iterations) : config_.outer_iterations;
    const MatchSolveResult solved = solve(pose, outer, result);
    const bool enough = solved.lines + solved.planes >= config_.min_correspondences;
    const bool sane = pose.isFinite() && (pose.t - prediction.t).norm() < config_.cube_size;
    if (enough && result.constraint >= config_.min_constraint && sane)
    {
      result.status = MappingStatus::kOk;
      if (config_.sweep_span && result.constraint >= config_.span_min_constraint && motionChanged(frame))
      {
        result.span_solved = solveSpan(frame, prediction, pose);
      }
    }
    else if (enough && sane && solved.remapped)
    {
      result.status = MappingStatus::kRemapped;  // the prediction kept along the weak directions only
    }
    else
    {
      result.status = MappingStatus::kDegraded;
      pose = prediction;
    }
  }

  last_motion_ = frame.motion;
  last_motion_known_ = frame.status != OdometryStatus::kInitialized;
  correction_ = pose * frame.pose.inverse();
  result.pose = pose;
  result.correction = correction_;
  // A distorted first sweep would warp the map every later sweep registers against: it waits for the
  // next sweep's motion (deskew_first_late), or the map starts with the first sweep whose motion is known.
  pending_insert_ = !(frame.distorted && map_.cubeCount() == 0 && !config_.insert_distorted_first);
  run_started_ = true;
  pending_pose_ = pose;
  if (frozen_ || skip_first)
  {
    pending_insert_ = false;
  }
  else if (held_first_ && pending_insert_)
  {
    releaseHeldFirst(frame);
  }
  else if (!pending_insert_ && config_.deskew_first_late)
  {
    held_first_ = HeldSweep{ frame.corners, frame.surfs, pose, frame.stamp };
  }
  return result;
}

void LaserMapping::updateMap(MappingResult& result)
{
  map_.setLeafSizes(cornerLeaf(), surfLeaf());  // re-indexes only when the leaf scale changed
  if (pending_first_)
  {
    insertSweep(map_, &first_corners_, &first_surfs_, first_pose_);
    pending_first_ = false;
  }
  if (pending_insert_)
  {
    insert(pending_pose_);
    pending_insert_ = false;
  }
  if (config_.eviction_radius > 0.0 && !frozen_)
  {
    result.evicted_cubes = map_.evictBeyond(pending_pose_.t, config_.eviction_radius);
    evicted_total_ += result.evicted_cubes;
  }
  prepareSubmap(map_.indexOf(pending_pose_.t));
  result.map_corners = map_.cornerCount();
  result.map_surfs = map_.surfCount();
  result.cubes = map_.cubeCount();
}

std::vector<Pose> poseGrid(const Pose& centre, double radius, double step, double yaw, double yaw_step)
{
  std::vector<Pose> starts;
  const int n = step > 0.0 ? static_cast<int>(std::floor(radius / step + 1e-9)) : 0;
  const int m = yaw_step > 0.0 ? static_cast<int>(std::floor(yaw / yaw_step + 1e-9)) : 0;
  for (int i = -n; i <= n; ++i)
  {
    for (int j = -n; j <= n; ++j)
    {
      for (int k = -m; k <= m; ++k)
      {
        starts.emplace_back(Eigen::Quaterniond(Eigen::AngleAxisd(k * yaw_step, Eigen::Vector3d::UnitZ())) * centre.q,
                            centre.t + Eigen::Vector3d(i * step, j * step, 0.0));
      }
    }
  }
  return starts;
}

std::vector<ScoredPose> LaserMapping::bestStarts(const Cloud& corners, const Cloud& surfs,
                                                 const std::vector<Pose>& starts, double inlier_residual, int stride,
                                                 int keep)
{
  std::vector<ScoredPose> scored;
  scored.reserve(starts.size());
  for (const Pose& start : starts)
  {
    prepareSubmapAround(start.t);
    scored.push_back(ScoredPose{ start, fitness(corners, surfs, start, inlier_residual, stride).inlier_share });
  }
  const std::size_t n = std::min<std::size_t>(std::max(keep, 1), scored.size());
  std::partial_sort(scored.begin(), scored.begin() + n, scored.end(),
                    [](const ScoredPose& a, const ScoredPose& b) { return a.score > b.score; });
  scored.resize(n);
  return scored;
}

CubeMap LaserMapping::buildMap(const std::vector<MapSweep>& sweeps, const LaserMappingConfig& config)
{
  CubeMap map(config.cube_size, config.corner_leaf_size, config.surf_leaf_size);
  for (const MapSweep& sweep : sweeps)
  {
    insertSweep(map, sweep.corners.get(), sweep.surfs.get(), sweep.pose);
  }
  return map;
}

void LaserMapping::rebuildMap(const std::vector<MapSweep>& sweeps, const Pose& change)
{
  LaserMappingConfig scaled = config_;
  scaled.corner_leaf_size = cornerLeaf();
  scaled.surf_leaf_size = surfLeaf();
  replaceMap(buildMap(sweeps, scaled), change);
}

void LaserMapping::replaceMap(CubeMap map, const Pose& change)
{
  map_ = std::move(map);
  correction_ = change * correction_;
  pending_pose_ = change * pending_pose_;
  prepareSubmap(map_.indexOf(pending_pose_.t));
}

void LaserMapping::startIn(CubeMap map, const Pose& correction)
{
  reset();
  continued_ = true;
  map_ = std::move(map);
  correction_ = correction;
  pending_pose_ = correction;
  prepareSubmap(map_.indexOf(pending_pose_.t));
}

void LaserMapping::loadMap(const Cloud& corners, const Cloud& surfs)
{
  reset();
  // Without leaf sizes the map keeps every point as given; the leaf sizes then only index them.
  map_.setLeafSizes(0.0, 0.0);
  map_.insertCorners(corners);
  map_.insertSurfs(surfs);
  map_.setLeafSizes(cornerLeaf(), surfLeaf());
}

void LaserMapping::prepareSubmapAround(const Eigen::Vector3d& position)
{
  const CubeIndex centre = map_.indexOf(position);
  if (!submap_ready_ || centre != submap_centre_)
  {
    prepareSubmap(centre);
  }
}

MatchFitness LaserMapping::fitness(const Cloud& corners, const Cloud& surfs, const Pose& pose, double inlier_residual,
                                   int stride) const
{
  MatchFitness f;
  double residual_sum = 0.0;
  const std::size_t step = static_cast<std::size_t>(std::max(stride, 1));
  auto count = [&](double residual)
  {
    ++f.matched;
    residual_sum += residual;
    f.inliers += residual < inlier_residual;
  };
  if (static_cast<int>(submap_corners_.size()) >= config_.min_map_corners)
  {
    for (std::size_t i = 0; i < corners.size(); i += step)
    {
      ++f.tried;
      LineMatch m;
      if (matchEdge(corners.points[i], pose, m))
      {
        count((freeAxisProjection(m) * (pose * m.point - m.a).cross(m.direction)).norm());
      }
    }
  }
  else
  {
    f.tried += static_cast<int>((corners.size() + step - 1) / step);
  }
  if (static_cast<int>(submap_surfs_.size()) >= config_.min_map_surfs)
  {
    for (std::size_t i = 0; i < surfs.size(); i += step)
    {
      ++f.tried;
      PlaneMatch m;
      if (matchPlane(surfs.points[i], pose, m))
      {
        count(std::fabs(m.normal.dot(pose * m.point) + m.d));
      }
    }
  }
  else
  {
    f.tried += static_cast<int>((surfs.size() + step - 1) / step);
  }
  f.inlier_share = f.tried > 0 ? static_cast<double>(f.inliers) / f.tried : 0.0;
  f.mean_residual = f.matched > 0 ? residual_sum / f.matched : 0.0;
  return f;
}

}  // namespace aloam
