#include "aloam_nodelet/core/localizer.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <sstream>
#include <utility>

#include "aloam_nodelet/core/voxel_filter.h"

namespace aloam
{
const char* toString(LocalizationState state)
{
  switch (state)
  {
    case LocalizationState::kUninitialized:
      return "uninitialized";
    case LocalizationState::kLocalizing:
      return "localizing";
    case LocalizationState::kLocalized:
      return "localized";
    case LocalizationState::kLost:
      return "lost";
  }
  return "unknown";
}

std::optional<Pose> poseFromXyzRpy(const std::string& text)
{
  std::istringstream in(text);
  double v[6];
  for (double& x : v)
  {
    if (!(in >> x))
    {
      return std::nullopt;
    }
  }
  std::string rest;
  if (in >> rest)
  {
    return std::nullopt;
  }
  const Eigen::Quaterniond q = Eigen::AngleAxisd(v[5], Eigen::Vector3d::UnitZ()) *
                               Eigen::AngleAxisd(v[4], Eigen::Vector3d::UnitY()) *
                               Eigen::AngleAxisd(v[3], Eigen::Vector3d::UnitX());
  return Pose(q, Eigen::Vector3d(v[0], v[1], v[2]));
}

Localizer::Localizer(LocalizerConfig config) : config_(std::move(config)), mapping_(config_.mapping)
{
  mapping_.setFrozen(true);
  outer_iterations_ = config_.mapping.outer_iterations;
}

void Localizer::loadMap(const MapData& map)
{
  config_.mapping.cube_size = map.metadata.cube_size;
  config_.mapping.corner_leaf_size = map.metadata.corner_leaf_size;
  config_.mapping.surf_leaf_size = map.metadata.surf_leaf_size;
  mapping_.setConfig(config_.mapping);
  outer_iterations_ = config_.mapping.outer_iterations;
  mapping_.loadMap(map.corners, map.surfs);
  setGlobalCandidates(map);
  reset();
}

void Localizer::reset()
{
  state_ = LocalizationState::kUninitialized;
  correction_ = Pose();
  initial_pending_ = false;
  search_pending_ = false;
  rebase_pending_ = false;
  has_pose_ = false;
  start_pose_.reset();
  run_frames_ = 0;
  good_frames_ = bad_frames_ = lost_frames_ = 0;
}

void Localizer::restart(ResetReason reason)
{
  switch (reason)
  {
    case ResetReason::kNone:
      break;
    case ResetReason::kOdometryRestarted:
      rebase_pending_ = true;
      break;
    case ResetReason::kJumpedBack:
    {
      const bool initial = initial_pending_;
      const std::optional<Pose> start = start_pose_;
      reset();
      start_pose_ = start;
      if (initial)
      {
        initial_pending_ = true;  // initial_pose_ is still the one given
      }
      else if (start)
      {
        setInitialPose(*start);
      }
      break;
    }
    case ResetReason::kRequested:
      reset();
      break;
  }
}

void Localizer::setInitialPose(const Pose& map_from_sensor)
{
  initial_pose_ = map_from_sensor;
  initial_pending_ = true;
}

void Localizer::useOuterIterations(int outer)
{
  if (outer != outer_iterations_)
  {
    LaserMappingConfig c = mapping_.config();
    c.outer_iterations = outer;
    c.hard_frame_outer_iterations = std::max(outer, config_.mapping.hard_frame_outer_iterations);
    mapping_.setConfig(c);
    outer_iterations_ = outer;
  }
}

bool Localizer::fits(const MatchFitness& f, bool localized) const
{
  return f.inlier_share >= (localized ? config_.lost_share : config_.localized_share) &&
         f.mean_residual <= (localized ? config_.lost_mean_residual : config_.max_mean_residual);
}

Localizer::Scored Localizer::registerFrom(const OdometryFrame& frame, const Pose& start)
{
  mapping_.setCorrection(start * frame.pose.inverse());
  const MappingResult r = mapping_.registerFrame(frame);
  const MatchFitness f =
      mapping_.fitness(mapping_.registeredCorners(), mapping_.registeredSurfs(), r.pose, config_.inlier_residual);
  return Scored{ r.pose, f.inlier_share };
}

std::vector<Pose> Localizer::gridAround(const Pose& centre, double radius, double yaw) const
{
  return poseGrid(centre, radius, config_.search_step, yaw, config_.search_yaw_step);
}

std::vector<Localizer::Scored> Localizer::bestCoarse(const OdometryFrame& frame, const std::vector<Pose>& starts,
                                                     int keep)
{
  Cloud corners, surfs;
  if (frame.corners)
  {
    voxelDownsample(*frame.corners, config_.mapping.corner_leaf_size, corners);
  }
  if (frame.surfs)
  {
    voxelDownsample(*frame.surfs, config_.mapping.surf_leaf_size, surfs);
  }
  return mapping_.bestStarts(corners, surfs, starts, config_.search_inlier_residual, config_.search_stride, keep);
}

Localizer::Scored Localizer::searchAmong(const OdometryFrame& frame, const std::vector<Pose>& starts, int refine,
                                         int& candidates)
{
  candidates += static_cast<int>(starts.size());
  Scored best;
  best.score = -1.0;
  for (const Scored& start : bestCoarse(frame, starts, refine))
  {
    const Scored s = registerFrom(frame, start.pose);
    if (s.score > best.score)
    {
      best = s;
    }
  }
  return best;
}

void Localizer::setGlobalCandidates(const MapData& map)
{
  global_positions_.clear();
  const double spacing = std::max(config_.global_spacing, 0.1);
  if (!map.metadata.trajectory.empty())
  {
    // The mapped drive: where the sensor has been is where it is likely to be again.
    for (const Eigen::Vector3d& p : map.metadata.trajectory)
    {
      const bool far = std::all_of(global_positions_.begin(), global_positions_.end(),
                                   [&](const Eigen::Vector3d& q) { return (p - q).norm() >= spacing; });
      if (far)
      {
        global_positions_.push_back(p);
      }
    }
    return;
  }
  // No trajectory: every grid cell with enough plane points, at its ground (the lowest tenth of them)
  // plus the sensor height.
  constexpr std::size_t kMinPoints = 20;
  std::map<std::pair<long, long>, std::vector<float>> cells;
  for (const Point& p : map.surfs.points)
  {
    cells[{ static_cast<long>(std::floor(p.x / spacing)), static_cast<long>(std::floor(p.y / spacing)) }].push_back(
        p.z);
  }
  for (auto& [cell, z] : cells)
  {
    if (z.size() < kMinPoints)
    {
      continue;
    }
    std::nth_element(z.begin(), z.begin() + z.size() / 10, z.end());
    global_positions_.emplace_back((cell.first + 0.5) * spacing, (cell.second + 0.5) * spacing,
                                   z[z.size() / 10] + config_.sensor_height);
  }
}

std::vector<Pose> Localizer::globalStarts() const
{
  std::vector<Pose> starts;
  const int yaws = std::max(1, static_cast<int>(std::lround(2.0 * M_PI / config_.global_yaw_step)));
  for (const Eigen::Vector3d& p : global_positions_)
  {
    for (int k = 0; k < yaws; ++k)
    {
      starts.push_back(Pose(Eigen::Quaterniond(Eigen::AngleAxisd(k * 2.0 * M_PI / yaws, Eigen::Vector3d::UnitZ())), p));
    }
  }
  return starts;
}

LocalizationResult Localizer::process(const OdometryFrame& frame)
{
  using Clock = std::chrono::steady_clock;
  LocalizationResult out;
  out.stamp = frame.stamp;
  if (initial_pending_ && run_frames_ == 0)
  {
    start_pose_ = initial_pose_;  // a jump back to the data's start starts from it again
  }
  ++run_frames_;
  if (initial_pending_)
  {
    correction_ = initial_pose_ * frame.pose.inverse();
    state_ = LocalizationState::kLocalizing;
    good_frames_ = bad_frames_ = lost_frames_ = 0;
    search_pending_ = true;
    initial_pending_ = false;
    rebase_pending_ = false;  // the given pose is newer than the last answer
  }
  else if (rebase_pending_)
  {
    // Odometry restarted: the sensor is about where the last answer put it (one sweep of motion, or a few
    // if frames were skipped, the search covers them), in odometry's new world.
    rebase_pending_ = false;
    if (has_pose_)
    {
      correction_ = last_pose_ * frame.pose.inverse();
      if (state_ != LocalizationState::kLost)
      {
        state_ = LocalizationState::kLocalizing;
        good_frames_ = bad_frames_ = 0;
        search_pending_ = true;
      }
    }
  }
  const Pose kept = correction_;
  // Settled: localized, and the last frame fitted closely where odometry predicted it. Otherwise more
  // searches: after a start, odometry underestimates the motion for a few sweeps, and two searches per
  // frame fall behind (measured on KITTI: docs/accuracy.md#localization).
  const bool settled = state_ == LocalizationState::kLocalized && last_residual_ <= config_.settled_residual &&
                       last_step_ <= config_.settled_step;
  const Pose prediction = kept * frame.pose;
  useOuterIterations(settled ? config_.mapping.outer_iterations : config_.converge_outer_iterations);
  const auto start = Clock::now();
  if (state_ == LocalizationState::kUninitialized)
  {
    // Global localization, retried every retry_every frames while it finds nothing that fits.
    const bool due = lost_frames_++ % std::max(config_.retry_every, 1) == 0;
    if (!config_.global_localization || global_positions_.empty() || !due)
    {
      out.state = state_;
      return out;
    }
    const std::vector<Pose> starts = globalStarts();
    out.candidates = static_cast<int>(starts.size());
    Scored best;
    best.score = -1.0;
    for (const Scored& coarse : bestCoarse(frame, starts, config_.global_refine))
    {
      // The truth lies within half a candidate spacing and half a yaw step of the nearest candidate.
      const std::vector<Pose> around =
          gridAround(coarse.pose, 0.5 * config_.global_spacing, 0.5 * config_.global_yaw_step);
      const Scored s = searchAmong(frame, around, 1, out.candidates);
      if (s.score > best.score)
      {
        best = s;
      }
    }
    out.searched = true;
    correction_ = best.pose * frame.pose.inverse();
  }
  else if (search_pending_ || (state_ == LocalizationState::kLost && config_.retry_every > 0 && lost_frames_ > 0 &&
                               lost_frames_ % config_.retry_every == 0))
  {
    const std::vector<Pose> starts = gridAround(prediction, config_.search_radius, config_.search_yaw);
    const Scored best = searchAmong(frame, starts, config_.search_refine, out.candidates);
    correction_ = best.pose * frame.pose.inverse();
    out.searched = true;
  }
  search_pending_ = false;
  if (out.searched)
  {
    out.search_ms = std::chrono::duration<double, std::milli>(Clock::now() - start).count();
  }

  mapping_.setCorrection(correction_);
  MappingResult r = mapping_.registerFrame(frame);
  const MatchFitness f =
      mapping_.fitness(mapping_.registeredCorners(), mapping_.registeredSurfs(), r.pose, config_.inlier_residual);
  mapping_.updateMap(r);
  const bool ok = r.status != MappingStatus::kMapTooSmall && fits(f, state_ == LocalizationState::kLocalized);
  const Pose registered = r.pose * frame.pose.inverse();
  // A fitting frame after none: localizing from its registered pose.
  const auto startLocalizing = [&]
  {
    correction_ = registered;
    state_ = LocalizationState::kLocalizing;
    good_frames_ = 1;
    bad_frames_ = 0;
  };
  switch (state_)
  {
    case LocalizationState::kUninitialized:
      // The global search's best, registered: taken only if it fits, else the search runs again later.
      if (ok)
      {
        startLocalizing();
      }
      else
      {
        correction_ = kept;
        out.state = state_;
        out.fitness = f;
        out.mapping = r;
        return out;
      }
      break;
    case LocalizationState::kLocalizing:
      // Converging from the given pose: every solve is a step closer, fitting or not (yet).
      correction_ = registered;
      ok ? (bad_frames_ = 0, ++good_frames_) : (good_frames_ = 0, ++bad_frames_);
      break;
    case LocalizationState::kLocalized:
      // A frame that does not fit (unmapped space, a changed scene, a sweep of something else) is no ground
      // to move the pose on: odometry carries it. Taking such registrations when well constrained dragged
      // the pose 0.37-0.50 m over 6 sweeps of unmapped space (test_localizer).
      ok ? (bad_frames_ = 0) : ++bad_frames_;
      correction_ = ok ? registered : kept;
      break;
    case LocalizationState::kLost:
      ++lost_frames_;
      if (ok)
      {
        startLocalizing();
      }
      else
      {
        correction_ = kept;
      }
      break;
  }
  if (state_ != LocalizationState::kLost)
  {
    if (good_frames_ >= config_.frames_to_localize)
    {
      state_ = LocalizationState::kLocalized;
    }
    if (bad_frames_ >= config_.frames_to_lose)
    {
      state_ = LocalizationState::kLost;
      lost_frames_ = 0;
      good_frames_ = 0;
    }
  }
  last_residual_ = f.mean_residual;
  last_step_ = (r.pose.t - prediction.t).norm();
  out.answered = true;
  out.pose = correction_ * frame.pose;
  has_pose_ = true;
  last_pose_ = out.pose;
  out.correction = correction_;
  out.state = state_;
  out.fitness = f;
  out.mapping = r;
  out.fits = ok;
  return out;
}

}  // namespace aloam
