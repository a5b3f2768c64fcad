#include "aloam_nodelet/core/loop_closure.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <numeric>
#include <stdexcept>

#include <Eigen/Eigenvalues>

#include "aloam_nodelet/core/voxel_filter.h"

namespace aloam
{
namespace
{
double rotationAngle(const Eigen::Quaterniond& q)
{
  return Eigen::AngleAxisd(q.normalized()).angle();
}

Pose yawed(double yaw, const Eigen::Quaterniond& level, const Eigen::Vector3d& t)
{
  return Pose(Eigen::Quaterniond(Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ())) * level, t);
}

std::string format(const char* text, double a, double b)
{
  char buffer[160];
  std::snprintf(buffer, sizeof(buffer), text, a, b);
  return buffer;
}

std::size_t cloudBytes(const std::shared_ptr<const Cloud>& cloud)
{
  return cloud ? cloud->size() * sizeof(Point) : 0;
}
}  // namespace

Eigen::Matrix<double, 6, 6> loopSqrtInformation(double sigma_translation, double sigma_rotation,
                                                const std::vector<DegenerateDirection>& weak,
                                                const Eigen::Quaterniond& relative, double lever_arm)
{
  using Matrix6 = Eigen::Matrix<double, 6, 6>;
  using Vector6 = Eigen::Matrix<double, 6, 1>;
  const Matrix6 root = sqrtInformation(sigma_translation, sigma_rotation);
  Matrix6 information = root * root;
  for (const DegenerateDirection& d : weak)
  {
    // The residual's change for a unit motion of `to` along d: translation seen from `from`, rotation in
    // the frame of `to` (d's rotation part is the motion it gives a point lever_arm away).
    Vector6 v;
    v << relative * d.translation, d.rotation / lever_arm;
    const Vector6 iv = information * v;
    const double along = v.dot(iv);
    if (!(along > 0.0))
    {
      continue;
    }
    const double keep = std::clamp(d.share, 0.0, 1.0);  // unknown share (< 0): none
    information -= (1.0 - keep) * iv * iv.transpose() / along;
  }
  const Eigen::SelfAdjointEigenSolver<Matrix6> eig(0.5 * (information + information.transpose()));
  return eig.eigenvectors() * eig.eigenvalues().cwiseMax(0.0).cwiseSqrt().asDiagonal() * eig.eigenvectors().transpose();
}

const char* toString(LoopSource source)
{
  switch (source)
  {
    case LoopSource::kNearby:
      return "nearby";
    case LoopSource::kDescriptor:
      return "descriptor";
    case LoopSource::kSessionStart:
      return "session start";
  }
  return "?";
}

const char* toString(SessionTie tie)
{
  switch (tie)
  {
    case SessionTie::kNone:
      return "none";
    case SessionTie::kPending:
      return "pending";
    case SessionTie::kTied:
      return "tied";
    case SessionTie::kNotTied:
      return "not tied";
  }
  return "?";
}

LoopClosure::LoopClosure(LoopClosureConfig config) : config_(std::move(config)) {}

void LoopClosure::setConfig(const LoopClosureConfig& config)
{
  config_ = config;
  dropOldClouds();
}

void LoopClosure::reset()
{
  keyframes_.clear();
  graph_.clear();
  history_.clear();
  loop_edges_.clear();
  last_input_ = Pose();
  last_loop_path_ = -1.0;
  optimizations_ = 0;
  last_optimize_ms_ = 0.0;
  session_ = 0;
  session_begin_ = 0;
  tie_record_ = SIZE_MAX;
}

LoopGraph LoopClosure::exportGraph() const
{
  LoopGraph out;
  out.keyframes = keyframes_;
  out.edges = graph_.edges();
  out.descriptor = config_.descriptor;
  out.keyframe_corner_leaf = config_.keyframe_corner_leaf;
  out.keyframe_surf_leaf = config_.keyframe_surf_leaf;
  return out;
}

std::vector<std::string> LoopClosure::importGraph(LoopGraph graph)
{
  // Everything is checked before anything changes.
  int last_session = -1;
  for (std::size_t i = 0; i < graph.keyframes.size(); ++i)
  {
    const Keyframe& k = graph.keyframes[i];
    if (!k.pose.isFinite() || !std::isfinite(k.stamp) || !std::isfinite(k.path) || k.session < 0 ||
        std::fabs(k.pose.q.norm() - 1.0) > 1e-3)
    {
      throw std::invalid_argument("keyframe " + std::to_string(i) + " has a non-finite or invalid pose");
    }
    last_session = std::max(last_session, k.session);
  }
  for (std::size_t i = 0; i < graph.edges.size(); ++i)
  {
    const PoseGraphEdge& e = graph.edges[i];
    if (e.from >= graph.keyframes.size() || e.to >= graph.keyframes.size() || e.from == e.to || !e.isUsable())
    {
      throw std::invalid_argument("edge " + std::to_string(i) +
                                  " joins unknown keyframes or has an invalid measurement");
    }
  }
  std::vector<std::string> warnings;
  reset();
  const auto same = [](const ScanContextConfig& a, const ScanContextConfig& b)
  { return a.rings == b.rings && a.sectors == b.sectors && a.max_range == b.max_range && a.lift == b.lift; };
  if (!same(graph.descriptor, config_.descriptor))
  {
    // The whole sweeps the descriptors were made from are gone: the keyframe clouds stand in for them.
    for (Keyframe& k : graph.keyframes)
    {
      k.descriptor = k.corners || k.surfs
                         ? ScanContext::compute(k.corners ? *k.corners : Cloud(), k.surfs ? *k.surfs : Cloud(), k.pose,
                                                config_.descriptor)
                         : ScanContext();
    }
    warnings.push_back("the graph's place descriptors were made with other settings: remade from the keyframe clouds");
  }
  if (graph.keyframe_corner_leaf != config_.keyframe_corner_leaf ||
      graph.keyframe_surf_leaf != config_.keyframe_surf_leaf)
  {
    char text[200];
    std::snprintf(text, sizeof(text), "the graph's keyframe clouds have voxel leaves %.2f / %.2f m (now %.2f / %.2f m)",
                  graph.keyframe_corner_leaf, graph.keyframe_surf_leaf, config_.keyframe_corner_leaf,
                  config_.keyframe_surf_leaf);
    warnings.push_back(text);
  }
  keyframes_ = std::move(graph.keyframes);
  for (Keyframe& k : keyframes_)
  {
    k.pose.q.normalize();
    graph_.addNode(k.pose);
  }
  for (const PoseGraphEdge& e : graph.edges)
  {
    graph_.addEdge(e);
  }
  session_ = last_session + 1;
  session_begin_ = keyframes_.size();
  dropOldClouds();
  return warnings;
}

std::size_t LoopClosure::nearestLoaded(const Eigen::Vector3d& position, bool with_clouds) const
{
  std::size_t nearest = keyframes_.size();
  double best = 0.0;
  for (std::size_t i = 0; i < session_begin_; ++i)
  {
    const Keyframe& k = keyframes_[i];
    const double d = (k.pose.t - position).norm();
    if ((!with_clouds || k.corners || k.surfs) && (nearest == keyframes_.size() || d < best))
    {
      nearest = i;
      best = d;
    }
  }
  return nearest;
}

bool isKeyframeStep(const Pose& last, const Pose& pose, const LoopClosureConfig& config)
{
  const Pose step = last.inverse() * pose;
  return step.t.norm() >= config.keyframe_distance || rotationAngle(step.q) >= config.keyframe_angle;
}

std::optional<Pose> LoopClosure::keyframeReference() const
{
  return keyframes_.size() == session_begin_ ? std::nullopt : std::optional<Pose>(last_input_);
}

bool LoopClosure::isKeyframe(const Pose& pose) const
{
  const std::optional<Pose> last = keyframeReference();
  return !last || isKeyframeStep(*last, pose, config_);
}

bool LoopClosure::separated(const Keyframe& a, const Keyframe& b) const
{
  return a.session != b.session || (std::fabs(a.stamp - b.stamp) >= config_.min_loop_separation_time &&
                                    std::fabs(a.path - b.path) >= config_.min_loop_separation_path);
}

void LoopClosure::dropOldClouds()
{
  std::size_t bytes = 0;
  for (auto it = keyframes_.rbegin(); it != keyframes_.rend(); ++it)
  {
    bytes += cloudBytes(it->corners) + cloudBytes(it->surfs);
    if (bytes > config_.max_keyframe_bytes)
    {
      it->corners.reset();
      it->surfs.reset();
    }
  }
}

LoopClosureStats LoopClosure::stats() const
{
  LoopClosureStats s;
  s.keyframes = keyframes_.size();
  s.keyframes_loaded = session_begin_;
  if (session_begin_ > 0)
  {
    s.tie = SessionTie::kPending;
    if (tie_record_ < history_.size())
    {
      const LoopRecord& tie = history_[tie_record_];
      s.tie = tie.accepted ? SessionTie::kTied : SessionTie::kNotTied;
      s.tie_reason = tie.accepted ? "keyframe " + std::to_string(tie.from) : tie.reason;
    }
  }
  for (const Keyframe& k : keyframes_)
  {
    s.keyframes_with_clouds += k.corners || k.surfs;
    s.cloud_bytes += cloudBytes(k.corners) + cloudBytes(k.surfs);
  }
  s.tried = history_.size();
  s.accepted = static_cast<std::size_t>(
      std::count_if(history_.begin(), history_.end(), [](const LoopRecord& r) { return r.accepted; }));
  s.rejected = s.tried - s.accepted;
  s.optimizations = optimizations_;
  s.last_optimize_ms = last_optimize_ms_;
  return s;
}

std::vector<MapSweep> LoopClosure::mapSweeps() const
{
  std::vector<MapSweep> sweeps;
  sweeps.reserve(keyframes_.size());
  for (const Keyframe& k : keyframes_)
  {
    if (k.corners || k.surfs)
    {
      sweeps.push_back(MapSweep{ k.corners, k.surfs, k.pose });
    }
  }
  return sweeps;
}

std::size_t LoopClosure::keyframeAt(double stamp) const
{
  const auto begin = keyframes_.begin() + static_cast<std::ptrdiff_t>(session_begin_);
  const auto it =
      std::upper_bound(begin, keyframes_.end(), stamp, [](double s, const Keyframe& k) { return s < k.stamp; });
  return it == begin ? session_begin_ : static_cast<std::size_t>(it - keyframes_.begin()) - 1;
}

void LoopClosure::correctPoses(const std::vector<double>& stamps, const std::vector<Pose>& before,
                               std::vector<Pose>& poses) const
{
  for (std::size_t i = 0; i < poses.size() && i < stamps.size(); ++i)
  {
    const std::size_t k = keyframeAt(stamps[i]);
    if (k < before.size() && k < keyframes_.size())
    {
      poses[i] = keyframes_[k].pose * before[k].inverse() * poses[i];
    }
  }
}

LoopUpdate LoopClosure::addFrame(double stamp, const Pose& pose, const Cloud& corners, const Cloud& surfs,
                                 const Cloud* sweep)
{
  LoopUpdate update;
  if (!pose.isFinite() || !isKeyframe(pose))
  {
    return update;
  }
  update.keyframe = true;
  Keyframe k;
  k.stamp = stamp;
  auto c = std::make_shared<Cloud>();
  auto s = std::make_shared<Cloud>();
  voxelDownsample(corners, config_.keyframe_corner_leaf, *c);
  voxelDownsample(surfs, config_.keyframe_surf_leaf, *s);
  k.corners = c;
  k.surfs = s;
  k.descriptor = sweep ? ScanContext::compute(*sweep, Cloud(), pose, config_.descriptor)
                       : ScanContext::compute(*c, *s, pose, config_.descriptor);
  k.session = session_;
  const bool run_start = keyframes_.size() == session_begin_;
  if (run_start)
  {
    k.pose = pose;
    graph_.addNode(pose);
    // Over a loaded graph: the anchor, where the run's initial pose and its first registrations put this
    // keyframe relative to the nearest loaded one. Keeps the graph one piece (the first node alone is
    // fixed) even when the tie below fails; its sigmas are loose, so any verified loop outweighs it.
    const std::size_t near = nearestLoaded(pose.t, false);
    if (near < keyframes_.size())
    {
      PoseGraphEdge anchor;
      anchor.from = near;
      anchor.to = keyframes_.size();
      anchor.measured = keyframes_[near].pose.inverse() * pose;
      anchor.sqrt_information =
          sqrtInformation(config_.session_anchor_sigma_translation, config_.session_anchor_sigma_rotation);
      graph_.addEdge(anchor);
    }
  }
  else
  {
    // The odometry edge: the step since the last keyframe as mapping measured it.
    const Pose step = last_input_.inverse() * pose;
    const Keyframe& last = keyframes_.back();
    k.path = last.path + step.t.norm();
    k.pose = last.pose * step;
    graph_.addNode(k.pose);
    PoseGraphEdge edge;
    edge.from = keyframes_.size() - 1;
    edge.to = keyframes_.size();
    edge.measured = step;
    const double length = std::max(step.t.norm(), 0.1);
    edge.sqrt_information =
        sqrtInformation(config_.odometry_sigma_translation * length, config_.odometry_sigma_rotation * length);
    graph_.addEdge(edge);
  }
  last_input_ = pose;
  keyframes_.push_back(std::move(k));
  dropOldClouds();

  const Keyframe& current = keyframes_.back();
  if (last_loop_path_ >= 0.0 && current.path - last_loop_path_ < config_.loop_spacing)
  {
    return update;
  }
  const auto start = std::chrono::steady_clock::now();
  std::vector<LoopRecord> found = candidates();
  const bool tie = run_start && session_begin_ > 0;
  if (tie && found.empty())
  {
    LoopRecord none;
    none.to = none.from = keyframes_.size() - 1;
    none.to_stamp = none.from_stamp = current.stamp;
    none.source = LoopSource::kSessionStart;
    none.reason = "no loaded keyframe has clouds to register against";
    found.push_back(none);
  }
  for (LoopRecord& record : found)
  {
    if (record.from != record.to)
    {
      verify(record);
    }
    update.tried.push_back(record);
    history_.push_back(record);
    if (tie)
    {
      tie_record_ = history_.size() - 1;
    }
    if (record.accepted)
    {
      break;  // one loop per keyframe
    }
  }
  update.verify_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  if (update.tried.empty() || !update.tried.back().accepted)
  {
    return update;
  }

  const LoopRecord& loop = update.tried.back();
  PoseGraphEdge edge;
  edge.from = loop.from;
  edge.to = loop.to;
  edge.measured = loop.relative;
  edge.loop = true;
  const double residual = loop.fitness.mean_residual;
  edge.sqrt_information = loopSqrtInformation(std::max(config_.loop_sigma_translation, residual),
                                              std::max(config_.loop_sigma_rotation, 0.1 * residual), loop.weak,
                                              loop.relative.q, config_.matching.constraint_lever_arm);
  graph_.addEdge(edge);
  loop_edges_.emplace_back(graph_.edges().size() - 1, history_.size() - 1);
  PoseGraphOptions options;
  options.max_iterations = config_.graph_iterations;
  options.outlier_error = config_.loop_outlier_error;
  options.loop_loss_scale = config_.loop_loss_scale;
  update.graph = graph_.optimize(options);
  for (const std::size_t disabled : update.graph.disabled)
  {
    for (const auto& [edge_index, record] : loop_edges_)
    {
      if (edge_index == disabled)
      {
        history_[record].accepted = false;
        history_[record].reason = "inconsistent with the other loops (left out of the pose graph)";
      }
    }
  }
  last_loop_path_ = current.path;
  ++optimizations_;
  last_optimize_ms_ = update.graph.ms;
  if (!update.graph.solved)
  {
    return update;
  }
  const Pose before = keyframes_.back().pose;
  update.keyframes_before.reserve(keyframes_.size());
  for (std::size_t i = 0; i < keyframes_.size(); ++i)
  {
    update.keyframes_before.push_back(keyframes_[i].pose);
    keyframes_[i].pose = graph_.pose(i);
  }
  update.optimized = true;
  update.correction = keyframes_.back().pose * before.inverse();
  // The caller moves its map by `correction`: the newest keyframe's input pose becomes its corrected one.
  last_input_ = keyframes_.back().pose;
  return update;
}

std::vector<LoopRecord> LoopClosure::candidates() const
{
  std::vector<LoopRecord> out;
  const std::size_t current_index = keyframes_.size() - 1;
  const Keyframe& current = keyframes_.back();
  auto record = [&](std::size_t target, LoopSource source, double descriptor_distance)
  {
    LoopRecord r;
    r.from = target;
    r.to = current_index;
    r.from_stamp = keyframes_[target].stamp;
    r.to_stamp = current.stamp;
    r.source = source;
    r.descriptor_distance = descriptor_distance;
    return r;
  };

  // A run over a loaded graph starts with one candidate: its first keyframe against the nearest loaded
  // keyframe, wherever it is (the run's initial pose says the two are in one frame).
  if (current_index == session_begin_ && session_begin_ > 0)
  {
    const std::size_t target = nearestLoaded(current.pose.t, true);
    if (target < current_index)
    {
      out.push_back(
          record(target, LoopSource::kSessionStart, current.descriptor.match(keyframes_[target].descriptor).distance));
    }
    return out;
  }

  // Nearby: the closest keyframe to the current estimate, within a radius that grows with the path
  // travelled since the last loop (the drift that may have built up).
  const double since = current.path - std::max(last_loop_path_, 0.0);
  const double radius = config_.search_radius + config_.search_radius_growth * since;
  std::size_t nearest = current_index;
  double nearest_distance = radius;
  std::vector<std::size_t> eligible;
  for (std::size_t i = 0; i < current_index; ++i)
  {
    const Keyframe& k = keyframes_[i];
    if (!(k.corners || k.surfs) || !separated(k, current))
    {
      continue;
    }
    eligible.push_back(i);
    const double d = (k.pose.t - current.pose.t).norm();
    if (d <= nearest_distance)
    {
      nearest_distance = d;
      nearest = i;
    }
  }
  if (nearest != current_index)
  {
    out.push_back(
        record(nearest, LoopSource::kNearby, current.descriptor.match(keyframes_[nearest].descriptor).distance));
  }

  // Descriptor: the closest ring keys, then the full comparison over every sector shift.
  if (config_.use_descriptor && !eligible.empty() && !current.descriptor.empty())
  {
    std::vector<std::pair<float, std::size_t>> by_key;
    by_key.reserve(eligible.size());
    for (std::size_t i : eligible)
    {
      by_key.emplace_back((keyframes_[i].descriptor.ringKey() - current.descriptor.ringKey()).squaredNorm(), i);
    }
    const std::size_t n = std::min<std::size_t>(std::max(config_.descriptor_candidates, 1), by_key.size());
    std::partial_sort(by_key.begin(), by_key.begin() + n, by_key.end());
    std::size_t best = current_index;
    double best_distance = config_.max_descriptor_distance;
    for (std::size_t j = 0; j < n; ++j)
    {
      const double d = current.descriptor.match(keyframes_[by_key[j].second].descriptor).distance;
      if (d <= best_distance)
      {
        best_distance = d;
        best = by_key[j].second;
      }
    }
    if (best != current_index && best != nearest)
    {
      out.push_back(record(best, LoopSource::kDescriptor, best_distance));
    }
  }
  return out;
}

void LoopClosure::verify(LoopRecord& record) const
{
  const Keyframe& current = keyframes_[record.to];
  const Keyframe& target = keyframes_[record.from];

  // The target's neighbourhood in the corrected map, from keyframes far enough from the current one.
  Cloud corners, surfs, moved;
  for (const Keyframe& k : keyframes_)
  {
    if (!(k.corners || k.surfs) || !separated(k, current) || (k.pose.t - target.pose.t).norm() > config_.submap_radius)
    {
      continue;
    }
    for (const bool is_corners : { true, false })
    {
      const auto& cloud = is_corners ? k.corners : k.surfs;
      if (!cloud)
      {
        continue;
      }
      Cloud& into = is_corners ? corners : surfs;
      for (const Point& p : cloud->points)
      {
        into.points.push_back(transformPoint(k.pose, p));
      }
    }
  }
  voxelDownsample(corners, config_.matching.corner_leaf_size, moved);
  corners.swap(moved);
  voxelDownsample(surfs, config_.matching.surf_leaf_size, moved);
  surfs.swap(moved);
  if (static_cast<int>(corners.size()) < config_.matching.min_map_corners ||
      static_cast<int>(surfs.size()) < config_.matching.min_map_surfs)
  {
    record.reason = "target submap too small";
    return;
  }
  LaserMappingConfig matching = config_.matching;
  matching.threads = 1;
  // From a coarse start up to half a grid step off: as many searches as localization takes to converge.
  matching.outer_iterations = std::max(matching.outer_iterations, config_.outer_iterations);
  LaserMapping mapping(matching);
  mapping.loadMap(corners, surfs);
  mapping.setFrozen(true);

  // Where to start: the current estimate for a nearby candidate; for a descriptor candidate, the target's
  // position turned by the descriptor's yaw.
  Pose centre = current.pose;
  if (record.source == LoopSource::kDescriptor)
  {
    const ScanContextMatch m = current.descriptor.match(target.descriptor);
    centre = yawed(yawOf(target.pose) + m.yaw, levelling(current.pose), target.pose.t);
  }
  const std::vector<ScoredPose> coarse = mapping.bestStarts(
      *current.corners, *current.surfs,
      poseGrid(centre, config_.coarse_radius, config_.coarse_step, config_.coarse_yaw, config_.coarse_yaw_step),
      2.0 * config_.inlier_residual, 4, 2);

  OdometryFrame frame;
  frame.stamp = current.stamp;
  frame.status = OdometryStatus::kOk;
  frame.corners = current.corners;
  frame.surfs = current.surfs;
  bool registered = false;
  MappingResult best;
  for (const ScoredPose& start : coarse)
  {
    mapping.setCorrection(start.pose);  // frame.pose is the identity: the start is the prediction
    const MappingResult r = mapping.registerFrame(frame);
    const MatchFitness f =
        mapping.fitness(mapping.registeredCorners(), mapping.registeredSurfs(), r.pose, config_.inlier_residual);
    if (!registered || f.inlier_share > record.fitness.inlier_share)
    {
      registered = true;
      best = r;
      record.fitness = f;
    }
  }
  record.correction_m = (best.pose.t - current.pose.t).norm();
  record.correction_rad = rotationAngle(current.pose.q.conjugate() * best.pose.q);
  // The drift a loop may correct grows with the path between the two keyframes; across runs, with the path
  // of the current run since its start (where its initial pose placed it in the loaded map).
  const double path = current.session == target.session ? current.path - target.path : current.path;
  const double max_move = config_.max_correction + config_.max_correction_rate * path;
  const double max_turn = config_.max_correction_angle + config_.max_correction_angle_rate * path;
  // A loop that leaves a rotation weak, even mixed with a translation, would carry the current keyframe's
  // attitude error into the map (corridor loops kept their roll error, docs/loop_closure.md); weak
  // translations are accepted.
  const double max_rotation = config_.max_weak_rotation;
  const bool partial =
      best.status == MappingStatus::kRemapped &&
      static_cast<int>(best.degenerate.size()) <= config_.max_weak_directions &&
      std::none_of(best.degenerate.begin(), best.degenerate.end(),
                   [max_rotation](const DegenerateDirection& d) { return d.rotation.norm() > max_rotation; });
  if (best.status != MappingStatus::kOk && !partial)
  {
    record.reason = best.status == MappingStatus::kMapTooSmall ? "target submap too small"
                    : best.status == MappingStatus::kRemapped  ? "registration degenerate: " + describe(best.degenerate)
                                                               : "registration degraded (too few matches)";
  }
  else if (record.fitness.inlier_share < config_.min_inlier_share)
  {
    record.reason = format("inlier share %.2f below %.2f", record.fitness.inlier_share, config_.min_inlier_share);
  }
  else if (record.fitness.mean_residual > config_.max_mean_residual)
  {
    record.reason =
        format("mean residual %.3f m above %.3f m", record.fitness.mean_residual, config_.max_mean_residual);
  }
  else if (record.correction_m > max_move)
  {
    record.reason = format("correction %.1f m beyond the drift bound %.1f m", record.correction_m, max_move);
  }
  else if (record.correction_rad > max_turn)
  {
    record.reason = format("correction %.1f deg beyond the drift bound %.1f deg", record.correction_rad * 180.0 / M_PI,
                           max_turn * 180.0 / M_PI);
  }
  else
  {
    record.accepted = true;
    record.relative = target.pose.inverse() * best.pose;
    record.weak = best.degenerate;
  }
}

}  // namespace aloam
