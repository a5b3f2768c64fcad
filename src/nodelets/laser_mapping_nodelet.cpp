// Laser mapping nodelet: a shell over aloam::MappingSession. Every odometry frame is answered at once with a
// corrected pose (aft_mapped_to_init_high_frec). The frame is then registered against the map on the callback
// thread, unless mapping is behind: then the newest waiting frame is registered after the map update in
// progress and older ones are skipped (and counted). After the mapped pose is out, the map update (adding the
// frame, indexing the next submap) runs as the stage's after-the-pose job. README "Threads" has the picture.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <memory>

#include <dynamic_reconfigure/server.h>
#include <nodelet/nodelet.h>
#include <pluginlib/class_list_macros.hpp>
#include <ros/ros.h>
#include <sensor_msgs/PointCloud2.h>
#include <std_srvs/Trigger.h>

#include <aloam_nodelet/LaserMappingConfig.h>
#include <aloam_nodelet/SaveGraph.h>
#include <aloam_nodelet/SaveMap.h>
#include <aloam_nodelet/SaveTrajectory.h>

#include "aloam_nodelet/core/executor.h"
#include "aloam_nodelet/core/graph_file.h"
#include "aloam_nodelet/core/latest_slot.h"
#include "aloam_nodelet/core/localizer.h"
#include "aloam_nodelet/core/map_file.h"
#include "aloam_nodelet/core/mapping_session.h"
#include "aloam_nodelet/eval/trajectory_io.h"
#include "aloam_nodelet/ros/stage_messages.h"
#include "mapped_outputs.h"
#include "nodelet_common.h"
#include "param_utils.h"
#include "publish_utils.h"
#include "stage_monitor.h"

namespace aloam_nodelet
{
using aloam::ros_io::StampedOdometryFrame;

class LaserMappingNodelet : public nodelet::Nodelet
{
public:
  ~LaserMappingNodelet() override;

private:
  void onInit() override;
  void frameCb(const StampedOdometryFrame::ConstPtr& msg);
  void registerWaiting();  // registers the newest waiting frame and publishes its pose
  void updateMap();        // the after-the-pose job
  void publishUpdate();    // adds the registered frame to the map and publishes the clouds
  void closeLoops();       // loop closure: a lane job of its own after the map update
  void publishClouds(const aloam::OdometryFrame& frame, const aloam::MappingResult& result);
  void report(diagnostic_updater::DiagnosticStatusWrapper& s);
  bool saveMapCb(SaveMap::Request& request, SaveMap::Response& response);
  bool saveGraphCb(SaveGraph::Request& request, SaveGraph::Response& response);
  void loadGraph(const std::string& path);  // ~graph_file at start-up
  aloam::GraphFileInfo graphInfo();         // this run's settings, as a saved graph records them
  bool saveTrajectoryCb(SaveTrajectory::Request& request, SaveTrajectory::Response& response);
  bool resetCb(std_srvs::Trigger::Request& request, std_srvs::Trigger::Response& response);
  void reconfigureCb(const LaserMappingConfig& config);

  std::unique_ptr<aloam::MappingSession> session_;
  MappedOutputs outputs_;
  aloam::LatestSlot<StampedOdometryFrame::ConstPtr> waiting_;  // admitted, not yet registered
  // Held while a frame is registered; a frame arriving meanwhile waits in `waiting_`.
  std::mutex registering_;
  std::atomic<double> last_register_ms_{ 0.0 };
  double scan_period_ = 0.1;
  VerdictThrottle throttle_;
  StageMonitor monitor_;

  double map_publish_period_ = 2.0;
  int surround_every_ = 5;
  std::mutex publish_mutex_;  // map update and cloud publishing, from the pose path or the job
  ros::Time last_map_publish_;

  ros::Subscriber frame_sub_;
  ros::Publisher surround_pub_, map_pub_, registered_pub_;
  ros::ServiceServer save_map_srv_, save_trajectory_srv_, save_graph_srv_, reset_srv_;
  std::string graph_status_ = "none";  // ~graph_file: what loading it did, for the diagnostics
  std::unique_ptr<dynamic_reconfigure::Server<LaserMappingConfig>> reconfigure_server_;
  std::shared_ptr<aloam::Executor> executor_;  // this nodelet's threads, joined on unload
  // Loop closure after the map update, on the lane only (updater_ requests it, so it is stopped after it).
  aloam::Executor::Job looper_;
  // Runs updateMap() after the pose is out; declared last, so stopped first.
  aloam::Executor::Job updater_;
};

LaserMappingNodelet::~LaserMappingNodelet()
{
  // As in odometry: a frame's callback may still run during the unload, and it requests the lane job, which
  // is destroyed first. Shutting the subscriber down waits for that callback.
  frame_sub_.shutdown();
}

void LaserMappingNodelet::onInit()
{
  ros::NodeHandle& nh = getNodeHandle();
  ros::NodeHandle& pnh = getPrivateNodeHandle();
  const std::string& name = getName();

  // Read once at start-up; the rest comes through dynamic_reconfigure (reconfigureCb).
  aloam::MappingSessionConfig config;
  config.mapping.threads = boundedParam(pnh, name, "threads", config.mapping.threads, 1, 16);
  config.stamps = stampCheckParams(pnh, name);
  scan_period_ = config.stamps.scan_period;
  config.trajectory_max_poses = static_cast<std::size_t>(
      boundedParam(pnh, name, "trajectory_max_poses", static_cast<int>(config.trajectory_max_poses), 100, 100'000'000));
  executor_ = std::make_shared<aloam::Executor>(config.mapping.threads);
  session_ = std::make_unique<aloam::MappingSession>(config, executor_);
  map_publish_period_ = boundedParam(pnh, name, "map_publish_period", map_publish_period_, 0.0, 3600.0);
  surround_every_ = boundedParam(pnh, name, "surround_every", surround_every_, 1, 1000);
  outputs_.init(nh, pnh, name);

  warnOutOfRange<LaserMappingConfig>(pnh, name);
  reconfigure_server_ = std::make_unique<dynamic_reconfigure::Server<LaserMappingConfig>>(pnh);
  reconfigure_server_->setCallback([this](LaserMappingConfig& c, std::uint32_t) { reconfigureCb(c); });
  // After the reconfiguration (which switches loop closure on), before the diagnostics and the first frame.
  std::string graph_file;
  pnh.param<std::string>("graph_file", graph_file, "");
  if (!graph_file.empty())
  {
    loadGraph(graph_file);  // before the first frame: the run starts in the loaded map
  }

  surround_pub_ = nh.advertise<sensor_msgs::PointCloud2>("laser_cloud_surround", 2);
  map_pub_ = nh.advertise<sensor_msgs::PointCloud2>("laser_cloud_map", 2);
  registered_pub_ = nh.advertise<sensor_msgs::PointCloud2>("velodyne_cloud_registered", 2);
  save_map_srv_ = pnh.advertiseService("save_map", &LaserMappingNodelet::saveMapCb, this);
  save_trajectory_srv_ = pnh.advertiseService("save_trajectory", &LaserMappingNodelet::saveTrajectoryCb, this);
  save_graph_srv_ = pnh.advertiseService("save_graph", &LaserMappingNodelet::saveGraphCb, this);
  reset_srv_ = pnh.advertiseService("reset", &LaserMappingNodelet::resetCb, this);
  monitor_.init(nh, pnh, name, [this](diagnostic_updater::DiagnosticStatusWrapper& s) { report(s); });
  updater_ = executor_->makeJob([this] { updateMap(); });
  looper_ = executor_->makeJob([this] { closeLoops(); });
  frame_sub_ = nh.subscribe("laser_odom_frame", 5, &LaserMappingNodelet::frameCb, this);
}

void LaserMappingNodelet::frameCb(const StampedOdometryFrame::ConstPtr& msg)
{
  if (malformed(*msg, "laser_odom_frame", getName()))
  {
    return;
  }
  const aloam::Admission admission = session_->admit(msg->frame, static_cast<std::int64_t>(msg->header.stamp.toNSec()));
  if (!admission.taken)
  {
    if (throttle_.due(admission.verdict))
    {
      NODELET_WARN_STREAM(dropMessage(admission.verdict, "laser_odom_frame", msg->header.stamp, admission.step,
                                      session_->stats().stamps));
    }
    return;
  }
  if (admission.reset == aloam::ResetReason::kJumpedBack)
  {
    NODELET_WARN("time jumped back %.3f s (looping bag?): map reset", -admission.step);
  }
  else if (admission.reset == aloam::ResetReason::kOdometryRestarted)
  {
    NODELET_WARN("odometry started a new trajectory (reset or reloaded): map reset (%zu so far)",
                 session_->stats().odometry_restarts);
  }
  outputs_.publishHighRate(msg->header.stamp, admission.corrected, msg->frame.pose, msg->sensor_frame_id);

  if (waiting_.put(msg))
  {
    NODELET_WARN_THROTTLE(kThrottleSeconds, "mapping is behind: %zu frames skipped so far", waiting_.skipped());
  }
  // Not behind: register here, on the pose path, with no hand-over. Behind (the last registration took longer
  // than a sweep period): the lane registers the newest waiting frame after its map update, skipping older
  // ones; if the lane has not started since the last frame (no idle core), this thread runs it now.
  if (last_register_ms_.load() <= 1000.0 * scan_period_)
  {
    registerWaiting();
  }
  else if (!updater_.runIfPending())
  {
    updater_.request();
  }
}

void LaserMappingNodelet::registerWaiting()
{
  std::unique_lock<std::mutex> lock(registering_, std::try_to_lock);
  if (!lock.owns_lock())
  {
    return;  // the one registering now takes the waiting frame next
  }
  while (const std::optional<StampedOdometryFrame::ConstPtr> next = waiting_.take())
  {
    const StampedOdometryFrame& msg = **next;
    const auto start = std::chrono::steady_clock::now();
    publishUpdate();  // the previous frame's map update, unless the after-the-pose job got to it first
    const aloam::MappingResult result = session_->registerFrame(msg.frame);
    if (session_->stats().frames_in_map == 1)
    {
      outputs_.clearPath();  // a new map (the first frame, or after a reset)
    }
    outputs_.publishMapped(msg.header.stamp, result.pose, result.correction);
    const double ms = msSince(start);
    last_register_ms_ = ms;
    monitor_.frameDone(ms);
    if (result.status == aloam::MappingStatus::kDegraded)
    {
      NODELET_WARN_THROTTLE(kThrottleSeconds, "mapping degraded (%d edge, %d plane matches, constraint %.1f)",
                            result.corner_matches, result.plane_matches, result.constraint);
    }
    else if (result.status == aloam::MappingStatus::kRemapped)
    {
      NODELET_DEBUG_THROTTLE(kThrottleSeconds, "mapping partially degenerate, prediction kept along %s",
                             aloam::describe(result.degenerate).c_str());
    }
  }
  updater_.request();
}

void LaserMappingNodelet::publishUpdate()
{
  std::lock_guard<std::mutex> lock(publish_mutex_);
  aloam::OdometryFrame frame;
  aloam::MappingResult result;
  if (session_->updateMap(&frame, &result))
  {
    publishClouds(frame, result);
  }
}

void LaserMappingNodelet::updateMap()
{
  publishUpdate();
  looper_.request();  // its own job: never run by the pose path (runIfPending runs the map update only)
  if (!waiting_.empty())
  {
    registerWaiting();  // mapping was behind: the newest frame that came meanwhile
  }
}

void LaserMappingNodelet::loadGraph(const std::string& path)
{
  ros::NodeHandle& pnh = getPrivateNodeHandle();
  if (!session_->loopClosureEnabled())
  {
    graph_status_ = "ignored (loop_closure is off)";
    NODELET_WARN("~graph_file %s ignored: loading a graph needs loop_closure on", path.c_str());
    return;
  }
  // Where this run starts in the saved map: its first sweep's sensor pose (default: where the saved run
  // started, e.g. a robot that restarts from its dock).
  aloam::Pose initial;
  std::string text;
  pnh.param<std::string>("initial_pose", text, "");
  if (!text.empty())
  {
    const auto pose = aloam::poseFromXyzRpy(text);
    if (!pose)
    {
      graph_status_ = "not loaded: ~initial_pose '" + text + "' is not \"x y z roll pitch yaw\"";
      NODELET_ERROR("~graph_file %s not loaded: %s", path.c_str(), graph_status_.c_str());
      return;
    }
    initial = *pose;
  }
  try
  {
    aloam::GraphFile file = aloam::readGraphFile(path);
    std::vector<std::string> warnings = aloam::graphSettingsWarnings(file.info, graphInfo());
    const std::size_t keyframes = file.graph.keyframes.size(), edges = file.graph.edges.size();
    for (const std::string& w : session_->loadGraph(std::move(file.graph), initial))
    {
      warnings.push_back(w);
    }
    for (const std::string& w : warnings)
    {
      NODELET_WARN("graph %s: %s", path.c_str(), w.c_str());
    }
    graph_status_ = "loaded " + path;
    NODELET_INFO("graph %s loaded: %zu keyframes, %zu edges; this run starts at %s in its map", path.c_str(), keyframes,
                 edges, text.empty() ? "the saved run's start" : text.c_str());
  }
  catch (const std::exception& e)
  {
    graph_status_ = std::string("not loaded: ") + e.what();
    NODELET_ERROR("~graph_file not loaded, mapping starts a new map: %s", e.what());
  }
}

aloam::GraphFileInfo LaserMappingNodelet::graphInfo()
{
  aloam::GraphFileInfo info;
  getPrivateNodeHandle().param<std::string>("sensor", info.sensor, "");
  const aloam::LaserMappingConfig config = session_->mappingConfig();
  info.cube_size = config.cube_size;
  info.corner_leaf_size = config.corner_leaf_size;
  info.surf_leaf_size = config.surf_leaf_size;
  return info;
}

bool LaserMappingNodelet::saveGraphCb(SaveGraph::Request& request, SaveGraph::Response& response)
{
  const aloam::LoopGraph graph = session_->exportGraph();  // waits for loop work in progress
  if (graph.keyframes.empty())
  {
    response.success = false;
    response.message =
        session_->loopClosureEnabled() ? "the graph has no keyframe yet" : "no graph: loop_closure is off";
    return true;
  }
  try
  {
    aloam::writeGraphFile(request.path, graph, graphInfo());
    const auto loops = std::count_if(graph.edges.begin(), graph.edges.end(),
                                     [](const aloam::PoseGraphEdge& e) { return e.loop && e.enabled; });
    response.success = true;
    response.message = "wrote " + std::to_string(graph.keyframes.size()) + " keyframes and " +
                       std::to_string(graph.edges.size()) + " edges (" + std::to_string(loops) + " loops) to " +
                       request.path;
  }
  catch (const std::exception& e)
  {
    response.success = false;
    response.message = e.what();
  }
  return true;
}

void LaserMappingNodelet::closeLoops()
{
  const aloam::LoopStep step = session_->closeLoops();
  for (const aloam::LoopRecord& r : step.update.tried)
  {
    if (r.source == aloam::LoopSource::kSessionStart)
    {
      if (r.accepted)
      {
        NODELET_INFO(
            "this run is tied to the loaded graph: its first keyframe %zu registered against loaded "
            "keyframe %zu (%.2f m / %.2f deg correction)",
            r.to, r.from, r.correction_m, r.correction_rad * 180.0 / M_PI);
      }
      else
      {
        NODELET_WARN(
            "this run could not be tied to the loaded graph (%s): it goes on where its initial pose put "
            "it, held only loosely to the loaded keyframes until a loop with them closes",
            r.reason.c_str());
      }
    }
    else if (!r.accepted)
    {
      NODELET_DEBUG("loop %zu -> %zu rejected: %s", r.to, r.from, r.reason.c_str());
    }
  }
  if (!step.update.optimized)
  {
    return;
  }
  const aloam::LoopRecord& loop = step.update.tried.back();
  NODELET_INFO(
      "loop closed: keyframe %zu to %zu (%.1f s earlier), %.2f m / %.2f deg correction; graph %.1f ms, "
      "map built in %.1f ms, swapped in in %.1f ms%s%s",
      loop.to, loop.from, loop.to_stamp - loop.from_stamp, loop.correction_m, loop.correction_rad * 180.0 / M_PI,
      step.update.graph.ms, step.build_ms, step.rebuild_ms, loop.weak.empty() ? "" : "; weak along ",
      loop.weak.empty() ? "" : aloam::describe(loop.weak).c_str());
  // The whole path moves with the corrected keyframes.
  const aloam::RecordedTrajectory corrected = session_->trajectory();
  outputs_.replacePath(corrected.poses, corrected.stamps);
}

void LaserMappingNodelet::publishClouds(const aloam::OdometryFrame& frame, const aloam::MappingResult& result)
{
  std_msgs::Header header;
  header.stamp.fromSec(frame.stamp);
  header.frame_id = outputs_.mapFrame();
  if (registered_pub_.getNumSubscribers() > 0 && frame.full)
  {
    publishCloudIfSubscribed(registered_pub_, aloam::MappingSession::toMap(*aloam::fullAtSweepEnd(frame), result.pose),
                             header);
  }
  const std::size_t mapped = session_->stats().frames_mapped;
  if (surround_pub_.getNumSubscribers() > 0 && mapped % static_cast<std::size_t>(surround_every_) == 0)
  {
    publishCloudIfSubscribed(surround_pub_, session_->surround(result.pose), header);
  }
  if (map_pub_.getNumSubscribers() > 0 && map_publish_period_ > 0.0 &&
      (last_map_publish_.isZero() || (header.stamp - last_map_publish_).toSec() >= map_publish_period_ ||
       header.stamp < last_map_publish_))
  {
    last_map_publish_ = header.stamp;
    aloam::Cloud all;
    session_->withMap([&all](const aloam::CubeMap& map) { map.collectAll(all); });
    publishCloudIfSubscribed(map_pub_, all, header);
  }
}

void LaserMappingNodelet::report(diagnostic_updater::DiagnosticStatusWrapper& s)
{
  const aloam::MappingSessionStats stats = session_->stats();
  s.add("frames skipped (mapping behind)", waiting_.skipped());
  reportStamps(s, stats.stamps);
  s.add("odometry restarts (map reset)", stats.odometry_restarts);
  addMatchDiagnostics(s, stats.last, stats.degraded, stats.remapped);
  s.add("map edge points", stats.last.map_corners);
  s.add("map plane points", stats.last.map_surfs);
  s.add("map cubes", stats.last.cubes);
  const aloam::LaserMappingConfig& mapping = session_->mappingConfig();
  s.addf("leaves (edge / plane)", "%.2f / %.2f m (scale %g of the configured: %s)",
         mapping.corner_leaf_size * stats.last.leaf_scale, mapping.surf_leaf_size * stats.last.leaf_scale,
         stats.last.leaf_scale, stats.last.leaf_scale < 1.0 ? "confined scene" : "open scene");
  s.add("cubes evicted", stats.evicted_cubes);
  s.add("trajectory poses dropped (trajectory_max_poses)", stats.trajectory_dropped);
  s.add("loop closure keyframes", stats.loops.keyframes);
  s.add("loop closure keyframes loaded", stats.loops.keyframes_loaded);
  s.add("graph file", graph_status_);
  s.add("tie to the loaded graph", std::string(aloam::toString(stats.loops.tie)) +
                                       (stats.loops.tie_reason.empty() ? "" : ": " + stats.loops.tie_reason));
  s.add("loop closure keyframe clouds (MiB)", static_cast<double>(stats.loops.cloud_bytes) / (1024.0 * 1024.0));
  s.add("loops accepted", stats.loops.accepted);
  s.add("loops rejected", stats.loops.rejected);
  s.add("last pose graph solve (ms)", stats.loops.last_optimize_ms);
  s.add("last map rebuild (ms)", stats.last_build_ms);
  s.add("last map swap under the lock (ms)", stats.last_rebuild_ms);
  if (stats.last.status == aloam::MappingStatus::kDegraded)
  {
    s.summary(diagnostic_msgs::DiagnosticStatus::WARN, "degraded: too few or degenerate matches, prediction used");
  }
  else if (stats.last.status == aloam::MappingStatus::kRemapped)
  {
    s.summary(diagnostic_msgs::DiagnosticStatus::OK,
              "partially degenerate, remapped: prediction kept along " + aloam::describe(stats.last.degenerate));
  }
}

void LaserMappingNodelet::reconfigureCb(const LaserMappingConfig& c)
{
  aloam::LaserMappingConfig config = session_->mappingConfig();
  config.cube_size = c.cube_size;
  config.corner_leaf_size = c.corner_leaf_size;
  config.surf_leaf_size = c.surf_leaf_size;
  config.leaf_min_scale = c.leaf_min_scale;
  config.leaf_reference_range = c.leaf_reference_range;
  config.max_iterations = c.max_iterations;
  config.outer_iterations = c.outer_iterations;
  config.plane_neighbours = c.plane_neighbours;
  config.eviction_radius = c.eviction_radius;
  config.degeneracy_remap = c.degeneracy_remap;
  config.soft_remap = c.soft_remap;
  config.deskew_first_late = c.deskew_first_late;
  config.sweep_span = c.sweep_span;
  config.span_motion_change_deg = c.span_motion_change_deg;
  config.span_motion_change_m = c.span_motion_change_m;
  config.span_min_constraint = c.span_min_constraint;
  config.span_start_weight = c.span_start_weight;
  aloam::LoopClosureConfig loop;
  loop.matching = config;
  loop.keyframe_distance = c.keyframe_distance;
  loop.min_loop_separation_time = loop.min_loop_separation_path = c.min_loop_separation;
  loop.search_radius = c.loop_search_radius;
  loop.min_inlier_share = c.loop_min_inlier_share;
  loop.max_mean_residual = c.loop_max_mean_residual;
  loop.max_weak_directions = c.loop_max_weak_directions;
  loop.max_weak_rotation = c.loop_max_weak_rotation;
  loop.max_descriptor_distance = c.loop_max_descriptor_distance;
  session_->setLoopClosure(c.loop_closure, loop);
  // Waits for the frame being mapped; a new cube size re-buckets the map (no point is lost).
  const auto [before, after] = session_->setMappingConfig(config);
  NODELET_INFO("reconfigured: cube %.1f m, leaves %.2f / %.2f m, %d x %d iterations; map %zu points (was %zu)",
               config.cube_size, config.corner_leaf_size, config.surf_leaf_size, config.max_iterations,
               config.outer_iterations, after, before);
}

bool LaserMappingNodelet::saveMapCb(SaveMap::Request& request, SaveMap::Response& response)
{
  // A map localization can load again (aloam::writeMapFile): edge and plane points told apart, and a
  // sidecar with the frame, the parameters and the mapped positions (1 m apart).
  aloam::Cloud corners, surfs;
  session_->withMap([&](const aloam::CubeMap& map) { aloam::splitMap(map, corners, surfs); });  // with the last frame
  aloam::MapMetadata metadata;
  metadata.frame_id = outputs_.mapFrame();
  getPrivateNodeHandle().param<std::string>("sensor", metadata.sensor, "");
  const aloam::LaserMappingConfig config = session_->mappingConfig();
  metadata.cube_size = config.cube_size;
  metadata.corner_leaf_size = config.corner_leaf_size;
  metadata.surf_leaf_size = config.surf_leaf_size;
  std::vector<Eigen::Vector3d> positions;
  for (const aloam::Pose& pose : session_->trajectory().poses)
  {
    positions.push_back(pose.t);
  }
  metadata.trajectory = aloam::thinnedPositions(positions, 1.0);
  try
  {
    aloam::writeMapFile(request.path, corners, surfs, metadata);  // throws with the reason
    response.success = true;
    response.message = "wrote " + std::to_string(corners.size() + surfs.size()) + " points to " + request.path +
                       " (+ " + aloam::mapSidecarPath(request.path) + ")";
  }
  catch (const std::exception& e)
  {
    response.success = false;
    response.message = e.what();
  }
  return true;
}

bool LaserMappingNodelet::saveTrajectoryCb(SaveTrajectory::Request& request, SaveTrajectory::Response& response)
{
  if (request.format != "tum" && request.format != "kitti" && !request.format.empty())
  {
    response.success = false;
    response.message = "unknown format '" + request.format + "' (kitti or tum)";
    return true;
  }
  const aloam::RecordedTrajectory recorded = session_->trajectory();
  const std::vector<aloam::Pose> poses = request.format == "tum" ? recorded.poses : recorded.relativeToFirst();
  aloam::eval::Trajectory trajectory;
  trajectory.reserve(poses.size());
  for (const aloam::Pose& pose : poses)
  {
    trajectory.push_back(pose.isometry());
  }
  try
  {
    if (request.format == "tum")
    {
      aloam::eval::writeTumTrajectory(request.path, trajectory, recorded.stamps);
    }
    else
    {
      aloam::eval::writeKittiPoses(request.path, trajectory);
    }
  }
  catch (const std::exception& e)
  {
    response.success = false;
    response.message = e.what();
    return true;
  }
  response.success = true;
  response.message = "wrote " + std::to_string(trajectory.size()) + " poses to " + request.path;
  return true;
}

bool LaserMappingNodelet::resetCb(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& response)
{
  session_->requestReset();
  response.success = true;
  response.message = "map reset before the next frame";
  return true;
}

}  // namespace aloam_nodelet

PLUGINLIB_EXPORT_CLASS(aloam_nodelet::LaserMappingNodelet, nodelet::Nodelet)
