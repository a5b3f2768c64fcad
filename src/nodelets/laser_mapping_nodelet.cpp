// Laser mapping nodelet. Every odometry frame is answered at once with a corrected pose
// (aft_mapped_to_init_high_frec); a worker thread maps the newest frame, skipping (and counting) any that
// arrive while it is busy, so odometry never waits on mapping. Once the mapped pose is out, a thread of
// its own, started when a core is idle, adds the frame to the map and indexes the next submap.
#include <atomic>
#include <condition_variable>
#include <memory>
#include <optional>
#include <mutex>
#include <thread>

#include <nav_msgs/Odometry.h>
#include <nav_msgs/Path.h>
#include <dynamic_reconfigure/server.h>
#include <nodelet/nodelet.h>
#include <pcl/io/pcd_io.h>
#include <pcl/io/impl/pcd_io.hpp>
#include <pluginlib/class_list_macros.hpp>
#include <ros/ros.h>
#include <sensor_msgs/PointCloud2.h>
#include <std_srvs/Trigger.h>
#include <tf2_eigen/tf2_eigen.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_broadcaster.h>
#include <tf2_ros/transform_listener.h>

#include <aloam_nodelet/LaserMappingConfig.h>
#include <aloam_nodelet/SaveMap.h>
#include <aloam_nodelet/SaveTrajectory.h>

#include "aloam_nodelet/core/laser_mapping.h"
#include "aloam_nodelet/eval/trajectory_io.h"
#include "aloam_nodelet/ros/conversions.h"
#include "aloam_nodelet/ros/stage_messages.h"
#include "background_worker.h"
#include "nodelet_common.h"
#include "param_utils.h"
#include "publish_utils.h"
#include "stage_monitor.h"

namespace aloam_nodelet
{
class LaserMappingNodelet : public nodelet::Nodelet
{
public:
  ~LaserMappingNodelet() override;

private:
  void onInit() override;
  void frameCb(const aloam::ros_io::StampedOdometryFrame::ConstPtr& msg);
  void work();
  void registerFrameLocked(const aloam::ros_io::StampedOdometryFrame::ConstPtr& msg);
  void updateMapLocked();
  void publishPose(const std_msgs::Header& header, const aloam::MappingResult& result);
  void publishClouds(const aloam::ros_io::StampedOdometryFrame& msg, const aloam::MappingResult& result,
                     const std_msgs::Header& header);
  std::optional<aloam::Pose> baseFromSensor(const std::string& sensor_frame);
  bool saveMapCb(SaveMap::Request& request, SaveMap::Response& response);
  bool saveTrajectoryCb(SaveTrajectory::Request& request, SaveTrajectory::Response& response);
  bool resetCb(std_srvs::Trigger::Request& request, std_srvs::Trigger::Response& response);
  void reconfigureCb(const LaserMappingConfig& config);

  // The core and everything derived from it; held by the worker while it maps a frame.
  std::mutex core_mutex_;
  std::unique_ptr<aloam::LaserMapping> mapping_;
  nav_msgs::Path path_;
  aloam::eval::Trajectory trajectory_;
  std::vector<double> trajectory_stamps_;
  ros::Time last_map_publish_;
  std::size_t frames_mapped_ = 0;
  aloam::MappingResult last_result_;
  // The registered frame whose map update is still to come (updateMapLocked).
  aloam::ros_io::StampedOdometryFrame::ConstPtr unmapped_;
  std::size_t degraded_frames_ = 0;
  std::size_t remapped_frames_ = 0;
  StageMonitor monitor_;

  // Hand-over of the newest frame to the worker.
  std::mutex queue_mutex_;
  std::condition_variable queue_cv_;
  aloam::ros_io::StampedOdometryFrame::ConstPtr pending_;
  bool reset_requested_ = false;
  bool odometry_running_ = false;  // a frame of the current odometry trajectory was received
  std::size_t odometry_restarts_ = 0;
  std::size_t skipped_ = 0;
  StampGuard stamps_;
  std::atomic<bool> stop_{ false };
  std::thread worker_;

  // Correction map <- odometry world, for the full-rate answer (updated by the worker), and the
  // base_link <- sensor extrinsic for REP 105 frames (looked up once).
  std::mutex correction_mutex_;
  aloam::Pose correction_;
  std::optional<aloam::Pose> base_from_sensor_;

  std::string map_frame_, child_frame_;
  // REP 105: map -> odom -> base_link instead of camera_init -> aft_mapped. odom and map are base_link
  // at the first sweep.
  bool rep105_ = false;
  std::string rep105_map_frame_, odom_frame_, base_frame_;
  bool publish_tf_ = true;
  std::size_t path_max_poses_ = 10000;
  std::size_t trajectory_max_poses_ = 1'000'000;  // kept for save_trajectory: 28 h at 10 Hz, 136 MB
  double map_publish_period_ = 2.0;
  int surround_every_ = 5;

  ros::Subscriber frame_sub_;
  ros::Publisher mapped_pub_, high_rate_pub_, path_pub_, surround_pub_, map_pub_, registered_pub_;
  ros::ServiceServer save_map_srv_, save_trajectory_srv_, reset_srv_;
  std::unique_ptr<tf2_ros::TransformBroadcaster> tf_broadcaster_;
  tf2_ros::Buffer tf_buffer_;
  std::unique_ptr<tf2_ros::TransformListener> tf_listener_;
  std::unique_ptr<dynamic_reconfigure::Server<LaserMappingConfig>> reconfigure_server_;
  // Runs updateMapLocked after the pose is out; declared last, so stopped first.
  std::unique_ptr<BackgroundWorker> updater_;
};

LaserMappingNodelet::~LaserMappingNodelet()
{
  {
    // Under the queue's lock: set between the worker's check and its wait, the flag would be missed.
    std::lock_guard<std::mutex> lock(queue_mutex_);
    stop_ = true;
  }
  queue_cv_.notify_all();
  if (worker_.joinable())
  {
    worker_.join();
  }
}

void LaserMappingNodelet::onInit()
{
  ros::NodeHandle& nh = getNodeHandle();
  ros::NodeHandle& pnh = getPrivateNodeHandle();
  const std::string& name = getName();

  // Read once at start-up; the rest comes through dynamic_reconfigure (reconfigureCb).
  pnh.param<std::string>("map_frame", map_frame_, "camera_init");
  pnh.param<std::string>("child_frame", child_frame_, "aft_mapped");
  pnh.param("publish_tf", publish_tf_, publish_tf_);
  std::string tf_mode = "aloam";
  pnh.param("tf_mode", tf_mode, tf_mode);
  if (tf_mode != "aloam" && tf_mode != "rep105")
  {
    NODELET_WARN("tf_mode '%s' is neither aloam nor rep105; using aloam", tf_mode.c_str());
  }
  rep105_ = tf_mode == "rep105";
  pnh.param<std::string>("rep105_map_frame", rep105_map_frame_, "map");
  pnh.param<std::string>("odom_frame", odom_frame_, "odom");
  pnh.param<std::string>("base_frame", base_frame_, "base_link");
  path_max_poses_ = static_cast<std::size_t>(boundedParam(pnh, name, "path_max_poses", 10000, 1, 1'000'000));
  trajectory_max_poses_ =
      static_cast<std::size_t>(boundedParam(pnh, name, "trajectory_max_poses", 1'000'000, 100, 100'000'000));
  map_publish_period_ = boundedParam(pnh, name, "map_publish_period", map_publish_period_, 0.0, 3600.0);
  surround_every_ = boundedParam(pnh, name, "surround_every", surround_every_, 1, 1000);
  aloam::LaserMappingConfig config;
  config.threads = boundedParam(pnh, name, "threads", config.threads, 1, 16);
  mapping_ = std::make_unique<aloam::LaserMapping>(config);
  stamps_.setConfig(stampCheckParams(pnh, name));
  path_.header.frame_id = map_frame_;

  warnOutOfRange<LaserMappingConfig>(pnh, name);
  reconfigure_server_ = std::make_unique<dynamic_reconfigure::Server<LaserMappingConfig>>(pnh);
  reconfigure_server_->setCallback([this](LaserMappingConfig& c, std::uint32_t) { reconfigureCb(c); });

  tf_broadcaster_ = std::make_unique<tf2_ros::TransformBroadcaster>();
  if (rep105_)
  {
    tf_listener_ = std::make_unique<tf2_ros::TransformListener>(tf_buffer_);
  }
  mapped_pub_ = nh.advertise<nav_msgs::Odometry>("aft_mapped_to_init", 10);
  high_rate_pub_ = nh.advertise<nav_msgs::Odometry>("aft_mapped_to_init_high_frec", 10);
  path_pub_ = nh.advertise<nav_msgs::Path>("aft_mapped_path", 2);
  surround_pub_ = nh.advertise<sensor_msgs::PointCloud2>("laser_cloud_surround", 2);
  map_pub_ = nh.advertise<sensor_msgs::PointCloud2>("laser_cloud_map", 2);
  registered_pub_ = nh.advertise<sensor_msgs::PointCloud2>("velodyne_cloud_registered", 2);
  save_map_srv_ = pnh.advertiseService("save_map", &LaserMappingNodelet::saveMapCb, this);
  save_trajectory_srv_ = pnh.advertiseService("save_trajectory", &LaserMappingNodelet::saveTrajectoryCb, this);
  reset_srv_ = pnh.advertiseService("reset", &LaserMappingNodelet::resetCb, this);

  monitor_.init(nh, pnh, name,
                [this](diagnostic_updater::DiagnosticStatusWrapper& s)
                {
                  {
                    std::lock_guard<std::mutex> lock(queue_mutex_);
                    s.add("frames skipped (mapping behind)", skipped_);
                    stamps_.report(s);
                    s.add("odometry restarts (map reset)", odometry_restarts_);
                  }
                  std::lock_guard<std::mutex> lock(core_mutex_);
                  addMatchDiagnostics(s, last_result_, degraded_frames_, remapped_frames_);
                  s.add("map edge points", last_result_.map_corners);
                  s.add("map plane points", last_result_.map_surfs);
                  s.add("map cubes", last_result_.cubes);
                  s.add("cubes evicted", mapping_->totalEvictedCubes());
                  if (last_result_.status == aloam::MappingStatus::kDegraded)
                  {
                    s.summary(diagnostic_msgs::DiagnosticStatus::WARN,
                              "degraded: too few or degenerate matches, prediction used");
                  }
                  else if (last_result_.status == aloam::MappingStatus::kRemapped)
                  {
                    s.summary(diagnostic_msgs::DiagnosticStatus::OK,
                              "partially degenerate, remapped: prediction kept along " +
                                  aloam::describe(last_result_.degenerate));
                  }
                });
  updater_ = std::make_unique<BackgroundWorker>(
      [this]
      {
        std::lock_guard<std::mutex> lock(core_mutex_);
        updateMapLocked();
      });
  worker_ = std::thread(&LaserMappingNodelet::work, this);
  frame_sub_ = nh.subscribe("laser_odom_frame", 5, &LaserMappingNodelet::frameCb, this);
}

void LaserMappingNodelet::frameCb(const aloam::ros_io::StampedOdometryFrame::ConstPtr& msg)
{
  // A gap needs nothing here: the correction (map <- odometry world) is a frame offset, not a velocity, so
  // applying it after a gap extrapolates nothing; odometry restarts its own motion prior.
  bool reset_pending = false;
  {
    std::lock_guard<std::mutex> lock(queue_mutex_);
    const aloam::StampVerdict verdict = stamps_.check(msg->header.stamp);
    if (!aloam::isTaken(verdict))
    {
      if (stamps_.warningDue(verdict))
      {
        NODELET_WARN_STREAM(stamps_.dropMessage(verdict, "laser_odom_frame", msg->header.stamp));
      }
      return;
    }
    if (verdict == aloam::StampVerdict::kJumpedBack)
    {
      NODELET_WARN("time jumped back %.3f s (looping bag?): map reset", -stamps_.lastStep());
      reset_requested_ = true;
    }
    else if (msg->frame.status == aloam::OdometryStatus::kInitialized && odometry_running_)
    {
      // Odometry started a new trajectory at identity (its reset service, a reload, a restarted manager)
      // while the stamps went on: its poses no longer fit this map, and building on would corrupt it.
      ++odometry_restarts_;
      NODELET_WARN("odometry started a new trajectory (reset or reloaded): map reset (%zu so far)", odometry_restarts_);
      reset_requested_ = true;
    }
    odometry_running_ = true;
    reset_pending = reset_requested_;
  }

  aloam::Pose corrected;
  {
    std::lock_guard<std::mutex> lock(correction_mutex_);
    if (reset_pending)
    {
      correction_ = aloam::Pose();  // the old map's correction means nothing to the new one
    }
    corrected = correction_ * msg->frame.pose;
  }
  std_msgs::Header header = msg->header;
  header.frame_id = map_frame_;
  high_rate_pub_.publish(aloam::ros_io::toOdometryMsg(corrected, header, child_frame_));
  if (rep105_ && publish_tf_)
  {
    if (const auto base_from_sensor = baseFromSensor(msg->sensor_frame_id))
    {
      header.frame_id = odom_frame_;
      const aloam::Pose odom_to_base = *base_from_sensor * msg->frame.pose * base_from_sensor->inverse();
      tf_broadcaster_->sendTransform(aloam::ros_io::toTransformMsg(odom_to_base, header, base_frame_));
    }
  }

  std::lock_guard<std::mutex> lock(queue_mutex_);
  if (pending_)
  {
    ++skipped_;
    NODELET_WARN_THROTTLE(kThrottleSeconds, "mapping is behind: %zu frames skipped so far", skipped_);
  }
  pending_ = msg;
  queue_cv_.notify_one();
}

std::optional<aloam::Pose> LaserMappingNodelet::baseFromSensor(const std::string& sensor_frame)
{
  {
    std::lock_guard<std::mutex> lock(correction_mutex_);
    if (base_from_sensor_)
    {
      return base_from_sensor_;
    }
  }
  aloam::Pose extrinsic;
  if (!sensor_frame.empty() && sensor_frame != base_frame_)
  {
    try
    {
      const geometry_msgs::TransformStamped t = tf_buffer_.lookupTransform(base_frame_, sensor_frame, ros::Time(0));
      extrinsic = aloam::Pose(tf2::transformToEigen(t));
    }
    catch (const tf2::TransformException& e)
    {
      NODELET_WARN_THROTTLE(kThrottleSeconds, "rep105: no transform %s <- %s yet (%s)", base_frame_.c_str(),
                            sensor_frame.c_str(), e.what());
      return std::nullopt;
    }
  }
  std::lock_guard<std::mutex> lock(correction_mutex_);
  base_from_sensor_ = extrinsic;
  return base_from_sensor_;
}

void LaserMappingNodelet::work()
{
  while (!stop_)
  {
    aloam::ros_io::StampedOdometryFrame::ConstPtr msg;
    bool reset = false;
    {
      std::unique_lock<std::mutex> lock(queue_mutex_);
      queue_cv_.wait(lock, [this] { return stop_ || pending_; });
      if (stop_)
      {
        return;
      }
      msg.swap(pending_);
      std::swap(reset, reset_requested_);
    }
    const auto start = std::chrono::steady_clock::now();
    {
      std::lock_guard<std::mutex> lock(core_mutex_);
      updateMapLocked();  // the previous frame's, unless the updater got to it first
      if (reset)
      {
        mapping_->reset();
        path_.poses.clear();
        trajectory_.clear();
        trajectory_stamps_.clear();
      }
      registerFrameLocked(msg);
    }
    monitor_.frameDone(msSince(start));
    updater_->request();
  }
}

void LaserMappingNodelet::registerFrameLocked(const aloam::ros_io::StampedOdometryFrame::ConstPtr& msg)
{
  const aloam::MappingResult result = mapping_->registerFrame(msg->frame);
  {
    std::lock_guard<std::mutex> lock(correction_mutex_);
    correction_ = result.correction;
  }
  std_msgs::Header header;
  header.stamp = msg->header.stamp;
  header.frame_id = map_frame_;
  publishPose(header, result);
  // The map figures (map size, cubes, evictions) keep their last values until updateMapLocked.
  const aloam::MappingResult previous = last_result_;
  last_result_ = result;
  last_result_.map_corners = previous.map_corners;
  last_result_.map_surfs = previous.map_surfs;
  last_result_.cubes = previous.cubes;
  unmapped_ = msg;
  if (result.status == aloam::MappingStatus::kDegraded)
  {
    ++degraded_frames_;
    NODELET_WARN_THROTTLE(kThrottleSeconds, "mapping degraded (%d edge, %d plane matches, constraint %.1f)",
                          result.corner_matches, result.plane_matches, result.constraint);
  }
  else if (result.status == aloam::MappingStatus::kRemapped)
  {
    ++remapped_frames_;
    NODELET_DEBUG_THROTTLE(kThrottleSeconds, "mapping partially degenerate, prediction kept along %s",
                           aloam::describe(result.degenerate).c_str());
  }
  trajectory_.push_back(result.pose.isometry());
  trajectory_stamps_.push_back(msg->header.stamp.toSec());
  // Bounded like the paths; the oldest tenth goes at once, so that a full trajectory is not shifted per frame.
  if (trajectory_.size() > trajectory_max_poses_ + trajectory_max_poses_ / 10)
  {
    const auto drop = static_cast<long>(trajectory_.size() - trajectory_max_poses_);
    NODELET_WARN_THROTTLE(kThrottleSeconds,
                          "trajectory longer than trajectory_max_poses = %zu: oldest %ld poses "
                          "dropped (save_trajectory writes the rest)",
                          trajectory_max_poses_, drop);
    trajectory_.erase(trajectory_.begin(), trajectory_.begin() + drop);
    trajectory_stamps_.erase(trajectory_stamps_.begin(), trajectory_stamps_.begin() + drop);
  }
}

void LaserMappingNodelet::updateMapLocked()
{
  if (!unmapped_)
  {
    return;
  }
  // The frame joins the map, and the submap is indexed for the next frame.
  mapping_->updateMap(last_result_);
  ++frames_mapped_;
  std_msgs::Header header;
  header.stamp = unmapped_->header.stamp;
  header.frame_id = map_frame_;
  publishClouds(*unmapped_, last_result_, header);
  unmapped_.reset();
}

void LaserMappingNodelet::publishPose(const std_msgs::Header& header, const aloam::MappingResult& result)
{
  const nav_msgs::Odometry odom = aloam::ros_io::toOdometryMsg(result.pose, header, child_frame_);
  mapped_pub_.publish(odom);
  if (publish_tf_ && !rep105_)
  {
    tf_broadcaster_->sendTransform(aloam::ros_io::toTransformMsg(result.pose, header, child_frame_));
  }
  else if (publish_tf_)
  {
    std::optional<aloam::Pose> base_from_sensor;
    {
      std::lock_guard<std::mutex> lock(correction_mutex_);
      base_from_sensor = base_from_sensor_;
    }
    if (base_from_sensor)
    {
      std_msgs::Header tf_header = header;
      tf_header.frame_id = rep105_map_frame_;
      const aloam::Pose map_to_odom = *base_from_sensor * result.correction * base_from_sensor->inverse();
      tf_broadcaster_->sendTransform(aloam::ros_io::toTransformMsg(map_to_odom, tf_header, odom_frame_));
    }
  }

  geometry_msgs::PoseStamped pose;
  pose.header = header;
  pose.pose = odom.pose.pose;
  appendAndPublish(path_, pose, path_max_poses_, path_pub_);
}

void LaserMappingNodelet::publishClouds(const aloam::ros_io::StampedOdometryFrame& msg,
                                        const aloam::MappingResult& result, const std_msgs::Header& header)
{
  if (registered_pub_.getNumSubscribers() > 0 && msg.frame.full)
  {
    aloam::Cloud world;
    world.points.reserve(msg.frame.full->size());
    for (const aloam::Point& p : msg.frame.full->points)
    {
      world.points.push_back(aloam::transformPoint(result.pose, p));
    }
    aloam::setUnorganized(world);
    publishCloudIfSubscribed(registered_pub_, world, header);
  }
  if (surround_pub_.getNumSubscribers() > 0 && frames_mapped_ % static_cast<std::size_t>(surround_every_) == 0)
  {
    const aloam::LaserMappingConfig& config = mapping_->config();
    aloam::Cloud corners, surfs;
    mapping_->map().gather(mapping_->map().indexOf(result.pose.t), config.submap_half_xy, config.submap_half_z, corners,
                           surfs);
    corners += surfs;
    publishCloudIfSubscribed(surround_pub_, corners, header);
  }
  if (map_pub_.getNumSubscribers() > 0 && map_publish_period_ > 0.0 &&
      (last_map_publish_.isZero() || (header.stamp - last_map_publish_).toSec() >= map_publish_period_ ||
       header.stamp < last_map_publish_))
  {
    last_map_publish_ = header.stamp;
    aloam::Cloud all;
    mapping_->map().collectAll(all);
    publishCloudIfSubscribed(map_pub_, all, header);
  }
}

void LaserMappingNodelet::reconfigureCb(const LaserMappingConfig& c)
{
  // Waits for the frame being mapped; a new cube size re-buckets the map (no point is lost).
  std::lock_guard<std::mutex> lock(core_mutex_);
  updateMapLocked();  // the last frame joins the map as it was registered
  aloam::LaserMappingConfig config = mapping_->config();
  config.cube_size = c.cube_size;
  config.corner_leaf_size = c.corner_leaf_size;
  config.surf_leaf_size = c.surf_leaf_size;
  config.max_iterations = c.max_iterations;
  config.outer_iterations = c.outer_iterations;
  config.plane_neighbours = c.plane_neighbours;
  config.eviction_radius = c.eviction_radius;
  config.degeneracy_remap = c.degeneracy_remap;
  config.deskew_first_late = c.deskew_first_late;
  const std::size_t points_before = mapping_->map().cornerCount() + mapping_->map().surfCount();
  mapping_->setConfig(config);
  NODELET_INFO("reconfigured: cube %.1f m, leaves %.2f / %.2f m, %d x %d iterations; map %zu points (was %zu)",
               config.cube_size, config.corner_leaf_size, config.surf_leaf_size, config.max_iterations,
               config.outer_iterations, mapping_->map().cornerCount() + mapping_->map().surfCount(), points_before);
}

bool LaserMappingNodelet::saveMapCb(SaveMap::Request& request, SaveMap::Response& response)
{
  aloam::Cloud all;
  {
    std::lock_guard<std::mutex> lock(core_mutex_);
    updateMapLocked();  // the map includes the last registered frame
    mapping_->map().collectAll(all);
  }
  if (all.empty())
  {
    response.success = false;
    response.message = "the map is empty";
  }
  else
  {
    // PCL reports some write errors by return value and others by exception.
    bool written = false;
    try
    {
      written = pcl::io::savePCDFileBinary(request.path, all) == 0;
    }
    catch (const std::exception& e)
    {
      NODELET_WARN("save_map: %s", e.what());
    }
    response.success = written;
    response.message =
        written ? "wrote " + std::to_string(all.size()) + " points to " + request.path : "cannot write " + request.path;
  }
  return true;
}

bool LaserMappingNodelet::saveTrajectoryCb(SaveTrajectory::Request& request, SaveTrajectory::Response& response)
{
  std::lock_guard<std::mutex> lock(core_mutex_);
  try
  {
    if (request.format == "tum")
    {
      aloam::eval::writeTumTrajectory(request.path, trajectory_, trajectory_stamps_);
    }
    else if (request.format == "kitti" || request.format.empty())
    {
      aloam::eval::Trajectory relative;
      relative.reserve(trajectory_.size());
      for (const Eigen::Isometry3d& pose : trajectory_)
      {
        relative.push_back(trajectory_.front().inverse() * pose);
      }
      aloam::eval::writeKittiPoses(request.path, relative);
    }
    else
    {
      response.success = false;
      response.message = "unknown format '" + request.format + "' (kitti or tum)";
      return true;
    }
  }
  catch (const std::exception& e)
  {
    response.success = false;
    response.message = e.what();
    return true;
  }
  response.success = true;
  response.message = "wrote " + std::to_string(trajectory_.size()) + " poses to " + request.path;
  return true;
}

bool LaserMappingNodelet::resetCb(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& response)
{
  std::lock_guard<std::mutex> lock(queue_mutex_);
  reset_requested_ = true;
  response.success = true;
  response.message = "map reset before the next frame";
  return true;
}

}  // namespace aloam_nodelet

PLUGINLIB_EXPORT_CLASS(aloam_nodelet::LaserMappingNodelet, nodelet::Nodelet)
