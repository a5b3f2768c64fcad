#include "aloam_nodelet/core/mapping_session.h"

#include <chrono>
#include <stdexcept>
#include <utility>

namespace aloam
{
std::vector<Pose> RecordedTrajectory::relativeToFirst() const
{
  std::vector<Pose> relative;
  relative.reserve(poses.size());
  for (const Pose& pose : poses)
  {
    relative.push_back(poses.front().inverse() * pose);
  }
  return relative;
}

MappingSession::MappingSession(const MappingSessionConfig& config, std::shared_ptr<Executor> executor)
  : admission_(config.stamps)
  , trajectory_max_poses_(config.trajectory_max_poses)
  , mapping_(config.mapping, std::move(executor))
  , loop_enabled_(config.loop_closure)
  , loop_gate_(config.loop)
  , loops_(config.loop)
{
}

void MappingSession::setLoopClosure(bool enabled, const LoopClosureConfig& config)
{
  std::lock_guard<std::mutex> loop(loop_mutex_);
  loops_.setConfig(config);
  std::lock_guard<std::mutex> lock(core_mutex_);
  loop_enabled_ = enabled;
  loop_gate_ = config;
}

bool MappingSession::loopClosureEnabled() const
{
  std::lock_guard<std::mutex> lock(core_mutex_);
  return loop_enabled_;
}

std::vector<std::string> MappingSession::loadGraph(LoopGraph graph, const Pose& initial)
{
  std::lock_guard<std::mutex> loop(loop_mutex_);
  LaserMappingConfig config;
  {
    std::lock_guard<std::mutex> lock(core_mutex_);
    if (!loop_enabled_)
    {
      throw std::logic_error("loop closure is off: a saved graph needs it");
    }
    config = mapping_.config();
  }
  if (!initial.isFinite())
  {
    throw std::invalid_argument("the initial pose is not finite");
  }
  std::vector<std::string> warnings = loops_.importGraph(std::move(graph));  // throws before changing anything
  // As after an accepted loop: the map is built off the core lock and swapped in under it.
  CubeMap map = LaserMapping::buildMap(loops_.mapSweeps(), config);
  std::lock_guard<std::mutex> lock(core_mutex_);
  if (mapping_.config().cube_size != config.cube_size ||
      mapping_.config().corner_leaf_size != config.corner_leaf_size ||
      mapping_.config().surf_leaf_size != config.surf_leaf_size)
  {
    map = LaserMapping::buildMap(loops_.mapSweeps(), mapping_.config());  // reconfigured meanwhile
  }
  // A new map and trajectory, as resetLocked() starts them, but the loop closure keeps what it loaded.
  resetLocked();
  loop_reset_pending_ = false;
  mapping_.startIn(std::move(map), initial);
  stats_.loops = loops_.stats();
  {
    std::lock_guard<std::mutex> admission(admission_mutex_);
    correction_ = initial;
    reset_pending_ = false;
  }
  return warnings;
}

LoopGraph MappingSession::exportGraph() const
{
  std::lock_guard<std::mutex> loop(loop_mutex_);
  return loops_.exportGraph();
}

LoopStep MappingSession::closeLoops()
{
  LoopStep step;
  std::lock_guard<std::mutex> loop(loop_mutex_);
  std::optional<MappedFrame> frame;
  {
    std::lock_guard<std::mutex> lock(core_mutex_);
    if (loop_reset_pending_)
    {
      loops_.reset();
      loop_reset_pending_ = false;
      stats_.loops = loops_.stats();
    }
    if (!loop_enabled_ || !to_offer_ || to_offer_->epoch != map_epoch_)
    {
      to_offer_.reset();
      return step;
    }
    std::swap(frame, to_offer_);
  }
  // Off the core lock: keyframe, candidates, verification, graph solve.
  step.offered = true;
  step.update = loops_.addFrame(frame->stamp, frame->pose, *frame->corners, *frame->surfs, frame->full.get());
  if (!step.update.optimized)
  {
    std::lock_guard<std::mutex> lock(core_mutex_);
    stats_.loops = loops_.stats();
    keyframe_reference_ = loops_.keyframeReference();
    return step;
  }
  // The corrected map is built off the core lock too; the lock only swaps it in.
  LaserMappingConfig config;
  {
    std::lock_guard<std::mutex> lock(core_mutex_);
    config = mapping_.config();
  }
  auto start = std::chrono::steady_clock::now();
  CubeMap map = LaserMapping::buildMap(loops_.mapSweeps(), config);
  step.build_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  std::lock_guard<std::mutex> lock(core_mutex_);
  start = std::chrono::steady_clock::now();
  updateMapLocked(nullptr, nullptr);  // a frame registered meanwhile joins the old map, which goes
  if (mapping_.config().cube_size != config.cube_size ||
      mapping_.config().corner_leaf_size != config.corner_leaf_size ||
      mapping_.config().surf_leaf_size != config.surf_leaf_size)
  {
    map = LaserMapping::buildMap(loops_.mapSweeps(), mapping_.config());  // reconfigured meanwhile
  }
  mapping_.replaceMap(std::move(map), step.update.correction);
  ++map_epoch_;
  {
    std::lock_guard<std::mutex> admission(admission_mutex_);
    correction_ = mapping_.correction();
  }
  // Every recorded pose follows the newest keyframe of this run at or before it (the run's first keyframe
  // for the poses before it: the graph holds it fixed unless the run continues a loaded graph).
  loops_.correctPoses(trajectory_.stamps, step.update.keyframes_before, trajectory_.poses);
  keyframe_reference_ = loops_.keyframeReference();
  step.rebuild_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  stats_.loops = loops_.stats();
  stats_.last_rebuild_ms = step.rebuild_ms;
  stats_.last_build_ms = step.build_ms;
  return step;
}

Admission MappingSession::admit(const OdometryFrame& frame, std::int64_t stamp_ns)
{
  std::lock_guard<std::mutex> lock(admission_mutex_);
  Admission out;
  static_cast<StampAdmission&>(out) = admission_.admit(frame, stamp_ns);
  if (!out.taken)
  {
    return out;
  }
  // A gap needs nothing here: the correction (map <- odometry world) is a frame offset, not a velocity, so
  // applying it after a gap extrapolates nothing; odometry restarts its own motion prior. After a jump back
  // or an odometry restart the frames' poses no longer fit this map, and building on would corrupt it.
  if (out.reset != ResetReason::kNone)
  {
    reset_pending_ = true;
    correction_ = Pose();  // the old map's correction means nothing to the new one
  }
  out.corrected = correction_ * frame.pose;
  return out;
}

void MappingSession::requestReset()
{
  std::lock_guard<std::mutex> lock(admission_mutex_);
  reset_pending_ = true;
}

MappingResult MappingSession::registerFrame(const OdometryFrame& frame)
{
  std::lock_guard<std::mutex> lock(core_mutex_);
  updateMapLocked(nullptr, nullptr);  // the previous frame's, unless the after-the-pose work got to it first
  bool reset = false;
  {
    std::lock_guard<std::mutex> admission(admission_mutex_);
    std::swap(reset, reset_pending_);
  }
  if (reset)
  {
    resetLocked();
  }
  const MappingResult result = mapping_.registerFrame(frame);
  {
    std::lock_guard<std::mutex> admission(admission_mutex_);
    correction_ = result.correction;
  }
  // The map figures (map size, cubes, evictions) keep their last values until the map update.
  const MappingResult previous = stats_.last;
  stats_.last = result;
  stats_.last.map_corners = previous.map_corners;
  stats_.last.map_surfs = previous.map_surfs;
  stats_.last.cubes = previous.cubes;
  ++stats_.frames_registered;
  ++stats_.frames_in_map;
  stats_.degraded += result.status == MappingStatus::kDegraded ? 1 : 0;
  stats_.remapped += result.status == MappingStatus::kRemapped ? 1 : 0;
  unmapped_ = frame;
  has_unmapped_ = true;

  trajectory_.poses.push_back(result.pose);
  trajectory_.stamps.push_back(frame.stamp);
  // The oldest tenth goes at once, so that a full trajectory is not shifted per frame.
  if (trajectory_.poses.size() > trajectory_max_poses_ + trajectory_max_poses_ / 10)
  {
    const auto drop = static_cast<long>(trajectory_.poses.size() - trajectory_max_poses_);
    stats_.trajectory_dropped += static_cast<std::size_t>(drop);
    trajectory_.poses.erase(trajectory_.poses.begin(), trajectory_.poses.begin() + drop);
    trajectory_.stamps.erase(trajectory_.stamps.begin(), trajectory_.stamps.begin() + drop);
  }
  return result;
}

bool MappingSession::updateMap(OdometryFrame* added, MappingResult* result)
{
  std::lock_guard<std::mutex> lock(core_mutex_);
  return updateMapLocked(added, result);
}

bool MappingSession::updateMapLocked(OdometryFrame* added, MappingResult* result)
{
  if (!has_unmapped_)
  {
    return false;
  }
  mapping_.updateMap(stats_.last);
  ++stats_.frames_mapped;
  // Only a frame that would become a keyframe is copied for the loop closure (which decides again).
  if (loop_enabled_ && !unmapped_.distorted &&
      (!keyframe_reference_ || isKeyframeStep(*keyframe_reference_, stats_.last.pose, loop_gate_)))
  {
    to_offer_ = MappedFrame{ stats_.last.stamp,
                             stats_.last.pose,
                             std::make_shared<const Cloud>(mapping_.registeredCorners()),
                             std::make_shared<const Cloud>(mapping_.registeredSurfs()),
                             unmapped_.full,
                             map_epoch_ };
  }
  stats_.evicted_cubes = mapping_.totalEvictedCubes();
  has_unmapped_ = false;
  if (added)
  {
    *added = unmapped_;
  }
  if (result)
  {
    *result = stats_.last;
  }
  unmapped_ = OdometryFrame();  // the clouds go with the last reference
  return true;
}

void MappingSession::resetLocked()
{
  mapping_.reset();
  to_offer_.reset();
  keyframe_reference_.reset();
  ++map_epoch_;
  loop_reset_pending_ = true;  // the loop closure forgets its keyframes at the next closeLoops()
  stats_.frames_in_map = 0;
  trajectory_.poses.clear();
  trajectory_.stamps.clear();
  has_unmapped_ = false;
  unmapped_ = OdometryFrame();
}

std::pair<std::size_t, std::size_t> MappingSession::setMappingConfig(const LaserMappingConfig& config)
{
  std::lock_guard<std::mutex> lock(core_mutex_);
  updateMapLocked(nullptr, nullptr);  // the last frame joins the map as it was registered
  const std::size_t before = mapping_.map().cornerCount() + mapping_.map().surfCount();
  mapping_.setConfig(config);
  return { before, mapping_.map().cornerCount() + mapping_.map().surfCount() };
}

LaserMappingConfig MappingSession::mappingConfig() const
{
  std::lock_guard<std::mutex> lock(core_mutex_);
  return mapping_.config();
}

void MappingSession::setMaxGapSweeps(double sweeps)
{
  std::lock_guard<std::mutex> lock(admission_mutex_);
  StampCheckConfig config = admission_.config();
  config.max_gap_sweeps = sweeps;
  admission_.setConfig(config);
}

Cloud MappingSession::toMap(const Cloud& cloud, const Pose& pose)
{
  Cloud out;
  out.points.reserve(cloud.size());
  for (const Point& p : cloud.points)
  {
    out.points.push_back(transformPoint(pose, p));
  }
  setUnorganized(out);
  return out;
}

Cloud MappingSession::surround(const Pose& pose) const
{
  std::lock_guard<std::mutex> lock(core_mutex_);
  const LaserMappingConfig& config = mapping_.config();
  Cloud corners, surfs;
  mapping_.map().gather(mapping_.map().indexOf(pose.t), config.submap_half_xy, config.submap_half_z, corners, surfs);
  corners += surfs;
  return corners;
}

RecordedTrajectory MappingSession::trajectory() const
{
  std::lock_guard<std::mutex> lock(core_mutex_);
  return trajectory_;
}

MappingSessionStats MappingSession::stats() const
{
  MappingSessionStats out;
  {
    std::lock_guard<std::mutex> lock(core_mutex_);
    out = stats_;
  }
  std::lock_guard<std::mutex> lock(admission_mutex_);
  out.odometry_restarts = admission_.odometryRestarts();
  out.stamps = admission_.counts();
  return out;
}

}  // namespace aloam
