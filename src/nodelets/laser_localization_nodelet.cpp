// Laser localization nodelet: localizes every odometry frame in a saved map (aloam::Localizer) instead of
// building one. A fourth nodelet rather than a mode of the mapping nodelet: it shares the matching through
// the core (LaserMapping frozen inside Localizer), but none of mapping's map upkeep, services or
// reconfigure, and adds what mapping has no use for (initial pose, lost / localized state, pose search).
// Outputs as mapping's: aft_mapped_to_init, aft_mapped_to_init_high_frec, aft_mapped_path and the TF of
// tf_mode; the map once, latched, on laser_cloud_map.
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <utility>

#include <geometry_msgs/PoseWithCovarianceStamped.h>
#include <nodelet/nodelet.h>
#include <pluginlib/class_list_macros.hpp>
#include <ros/ros.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2_eigen/tf2_eigen.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_broadcaster.h>
#include <tf2_ros/transform_listener.h>

#include "aloam_nodelet/core/latest_slot.h"
#include "aloam_nodelet/core/localizer.h"
#include "aloam_nodelet/core/map_file.h"
#include "aloam_nodelet/core/rep105.h"
#include "aloam_nodelet/ros/conversions.h"
#include "aloam_nodelet/ros/stage_messages.h"
#include "mapped_outputs.h"
#include "nodelet_common.h"
#include "param_utils.h"
#include "stage_monitor.h"

namespace aloam_nodelet
{
class LaserLocalizationNodelet : public nodelet::Nodelet
{
public:
  ~LaserLocalizationNodelet() override;

private:
  void onInit() override;
  void frameCb(const aloam::ros_io::StampedOdometryFrame::ConstPtr& msg);
  void initialPoseCb(const geometry_msgs::PoseWithCovarianceStamped::ConstPtr& msg);
  void work();
  /// An initial pose in the map frame: the sensor's (tf_mode aloam) or base_link's (rep105).
  void setInitialPose(const aloam::Pose& pose);
  void applyPendingBasePose();
  void useInitialPose(const aloam::Pose& map_from_sensor);
  std::optional<aloam::Pose> lookup(const std::string& target, const std::string& source, const ros::Time& stamp);
  aloam::LocalizerConfig localizerParams(const ros::NodeHandle& pnh, const std::string& name) const;

  MappedOutputs outputs_;
  // What the initial pose is given in: the map frame and the sensor (tf_mode aloam), or REP 105's map frame
  // and base_link (rep105).
  bool rep105_ = false;
  std::string rep105_map_frame_, base_frame_;
  std::string map_error_;  // why no map is loaded (empty: loaded)

  std::mutex core_mutex_;
  std::unique_ptr<aloam::Localizer> localizer_;
  aloam::LocalizationResult last_;
  std::size_t searches_ = 0, lost_frames_ = 0, initial_poses_ = 0;
  double last_search_ms_ = 0.0;
  StageMonitor monitor_;

  std::mutex queue_mutex_;
  std::condition_variable queue_cv_;
  aloam::LatestSlot<aloam::ros_io::StampedOdometryFrame::ConstPtr> waiting_;  // the newest, not yet localized
  // Mapping's time policy (duplicates, late frames, jumps back, odometry restarts); a reset it reports goes
  // to the localizer with the next frame the worker takes, so it never lands before an older frame.
  aloam::FrameAdmission admission_;
  aloam::ResetReason pending_reset_ = aloam::ResetReason::kNone;
  VerdictThrottle throttle_;
  std::atomic<bool> stop_{ false };
  std::thread worker_;

  // map <- odometry world for the full-rate answer (none before the first pose).
  std::mutex correction_mutex_;
  aloam::Pose correction_;
  bool answered_ = false;
  std::string sensor_frame_;
  std::optional<aloam::Pose> pending_base_pose_;  // rep105: an initial pose waiting for the extrinsic

  ros::Subscriber frame_sub_, initial_pose_sub_;
  ros::Publisher map_pub_;
  tf2_ros::Buffer tf_buffer_;
  std::unique_ptr<tf2_ros::TransformListener> tf_listener_;
};

LaserLocalizationNodelet::~LaserLocalizationNodelet()
{
  // As in mapping and odometry: a callback may still run during the unload; shutting the subscribers down
  // waits for it, so none hands a frame to the worker stopped below or outlives the members it uses.
  frame_sub_.shutdown();
  initial_pose_sub_.shutdown();
  {
    std::lock_guard<std::mutex> lock(queue_mutex_);
    stop_ = true;
  }
  queue_cv_.notify_all();
  if (worker_.joinable())
  {
    worker_.join();
  }
}

aloam::LocalizerConfig LaserLocalizationNodelet::localizerParams(const ros::NodeHandle& pnh,
                                                                 const std::string& name) const
{
  aloam::LocalizerConfig c;
  c.mapping.threads = boundedParam(pnh, name, "threads", c.mapping.threads, 1, 16);
  c.inlier_residual = boundedParam(pnh, name, "inlier_residual", c.inlier_residual, 0.01, 5.0);
  c.localized_share = boundedParam(pnh, name, "localized_share", c.localized_share, 0.0, 1.0);
  c.lost_share = boundedParam(pnh, name, "lost_share", c.lost_share, 0.0, 1.0);
  c.max_mean_residual = boundedParam(pnh, name, "max_mean_residual", c.max_mean_residual, 0.0, 5.0);
  c.lost_mean_residual = boundedParam(pnh, name, "lost_mean_residual", c.lost_mean_residual, 0.0, 5.0);
  c.frames_to_localize = boundedParam(pnh, name, "frames_to_localize", c.frames_to_localize, 1, 1000);
  c.frames_to_lose = boundedParam(pnh, name, "frames_to_lose", c.frames_to_lose, 1, 1000);
  c.search_radius = boundedParam(pnh, name, "search_radius", c.search_radius, 0.0, 50.0);
  c.search_yaw = boundedParam(pnh, name, "search_yaw", c.search_yaw, 0.0, M_PI);
  c.retry_every = boundedParam(pnh, name, "retry_every", c.retry_every, 0, 100000);
  pnh.param("global_localization", c.global_localization, c.global_localization);
  return c;
}

void LaserLocalizationNodelet::onInit()
{
  ros::NodeHandle& nh = getNodeHandle();
  ros::NodeHandle& pnh = getPrivateNodeHandle();
  const std::string& name = getName();

  std::string map_file;
  pnh.param<std::string>("map", map_file, "");
  std::string tf_mode = "aloam";
  pnh.param("tf_mode", tf_mode, tf_mode);
  rep105_ = tf_mode == "rep105";
  pnh.param<std::string>("rep105_map_frame", rep105_map_frame_, "map");
  pnh.param<std::string>("base_frame", base_frame_, "base_link");
  admission_.setConfig(stampCheckParams(pnh, name));

  localizer_ = std::make_unique<aloam::Localizer>(localizerParams(pnh, name));
  aloam::MapData map;
  if (map_file.empty())
  {
    map_error_ = "no ~map given (a map file saved by laser_mapping's ~save_map or aloam_offline --save-map)";
  }
  else
  {
    try
    {
      map = aloam::readMapFile(map_file);
    }
    catch (const std::exception& e)
    {
      map_error_ = e.what();
    }
  }
  if (map_error_.empty())
  {
    for (const std::string& w : map.warnings)
    {
      NODELET_WARN("map %s: %s", map_file.c_str(), w.c_str());
    }
    localizer_->loadMap(map);
    NODELET_INFO("map %s: %zu edge, %zu plane points, frame %s, sensor %s, %zu global candidates", map_file.c_str(),
                 map.corners.size(), map.surfs.size(), map.metadata.frame_id.c_str(),
                 map.metadata.sensor.empty() ? "unknown" : map.metadata.sensor.c_str(),
                 localizer_->globalCandidates().size());
  }
  else
  {
    NODELET_ERROR("no map loaded, nothing will be localized: %s", map_error_.c_str());
  }
  if (map_error_.empty() && !pnh.hasParam("map_frame"))
  {
    pnh.setParam("map_frame", map.metadata.frame_id);  // the frame the map was built in, unless told otherwise
  }
  outputs_.init(nh, pnh, name);

  std::string initial;
  pnh.param<std::string>("initial_pose", initial, "");
  if (!initial.empty())
  {
    if (const auto pose = aloam::poseFromXyzRpy(initial))
    {
      setInitialPose(*pose);
      NODELET_INFO("initial pose %s (map frame)", initial.c_str());
    }
    else
    {
      NODELET_ERROR("~initial_pose '%s' is not \"x y z roll pitch yaw\": ignored", initial.c_str());
    }
  }

  monitor_.init(nh, pnh, name,
                [this](diagnostic_updater::DiagnosticStatusWrapper& s)
                {
                  {
                    std::lock_guard<std::mutex> lock(queue_mutex_);
                    s.add("frames skipped (localization behind)", waiting_.skipped());
                    reportStamps(s, admission_.counts());
                    s.add("odometry restarts (pose carried over)", admission_.odometryRestarts());
                  }
                  std::lock_guard<std::mutex> lock(core_mutex_);
                  const char* state = aloam::toString(last_.state);
                  s.add("state", state);
                  s.addf("inlier share", "%.3f", last_.fitness.inlier_share);
                  s.addf("mean residual (m)", "%.3f", last_.fitness.mean_residual);
                  s.add("points matched", last_.fitness.matched);
                  s.add("points tried", last_.fitness.tried);
                  s.add("pose searches", searches_);
                  s.addf("last search (ms)", "%.0f", last_search_ms_);
                  s.add("frames lost", lost_frames_);
                  s.add("initial poses received", initial_poses_);
                  if (!map_error_.empty())
                  {
                    s.summary(diagnostic_msgs::DiagnosticStatus::ERROR, "no map: " + map_error_);
                  }
                  else if (last_.state == aloam::LocalizationState::kLost)
                  {
                    s.summary(diagnostic_msgs::DiagnosticStatus::WARN,
                              "lost: the sweeps do not fit the map; publishing the odometry-propagated pose");
                  }
                  else if (last_.state == aloam::LocalizationState::kUninitialized)
                  {
                    s.summary(diagnostic_msgs::DiagnosticStatus::WARN,
                              "uninitialized: waiting for an initial pose on initialpose");
                  }
                  else
                  {
                    s.summary(diagnostic_msgs::DiagnosticStatus::OK, state);
                  }
                });

  tf_listener_ = std::make_unique<tf2_ros::TransformListener>(tf_buffer_);
  map_pub_ = nh.advertise<sensor_msgs::PointCloud2>("laser_cloud_map", 1, true);
  if (map_error_.empty())
  {
    aloam::Cloud all = map.corners;
    all += map.surfs;
    std_msgs::Header header;
    header.stamp = ros::Time::now();
    header.frame_id = outputs_.mapFrame();
    sensor_msgs::PointCloud2 msg;
    aloam::ros_io::toPointCloud2(all, header, msg);
    map_pub_.publish(msg);  // latched: rviz shows it whenever it connects
  }
  worker_ = std::thread(&LaserLocalizationNodelet::work, this);
  initial_pose_sub_ = nh.subscribe("initialpose", 2, &LaserLocalizationNodelet::initialPoseCb, this);
  frame_sub_ = nh.subscribe("laser_odom_frame", 5, &LaserLocalizationNodelet::frameCb, this);
}

std::optional<aloam::Pose> LaserLocalizationNodelet::lookup(const std::string& target, const std::string& source,
                                                            const ros::Time& stamp)
{
  try
  {
    // At the message's stamp if TF has it, else the latest.
    const ros::Time at = tf_buffer_.canTransform(target, source, stamp) ? stamp : ros::Time(0);
    return aloam::Pose(tf2::transformToEigen(tf_buffer_.lookupTransform(target, source, at)));
  }
  catch (const tf2::TransformException& e)
  {
    NODELET_WARN("no transform %s <- %s (%s)", target.c_str(), source.c_str(), e.what());
    return std::nullopt;
  }
}

void LaserLocalizationNodelet::initialPoseCb(const geometry_msgs::PoseWithCovarianceStamped::ConstPtr& msg)
{
  // The pose is the sensor's in the map frame (tf_mode aloam) or base_link's in rep105_map_frame (rep105);
  // a pose stamped in any other frame is converted through TF first.
  const std::string& frame = rep105_ ? rep105_map_frame_ : outputs_.mapFrame();
  aloam::Pose pose = aloam::ros_io::fromPoseMsg(msg->pose.pose);
  const std::string& from = msg->header.frame_id;
  if (!from.empty() && from != frame)
  {
    const auto to_map = lookup(frame, from, msg->header.stamp);
    if (!to_map)
    {
      NODELET_ERROR("initial pose in frame %s ignored: no transform to %s", from.c_str(), frame.c_str());
      return;
    }
    pose = *to_map * pose;
  }
  setInitialPose(pose);
}

void LaserLocalizationNodelet::setInitialPose(const aloam::Pose& pose)
{
  if (rep105_)
  {
    // base_link's pose: converted once the sensor frame (from the first sweep) and its extrinsic are known.
    {
      std::lock_guard<std::mutex> lock(correction_mutex_);
      pending_base_pose_ = pose;
    }
    applyPendingBasePose();
    return;
  }
  useInitialPose(pose);
}

void LaserLocalizationNodelet::applyPendingBasePose()
{
  std::optional<aloam::Pose> base_pose;
  std::string sensor_frame;
  {
    std::lock_guard<std::mutex> lock(correction_mutex_);
    base_pose = pending_base_pose_;
    sensor_frame = sensor_frame_;
  }
  if (!base_pose || sensor_frame.empty())
  {
    return;  // no pose waiting, or no sweep yet
  }
  const auto base_from_sensor = sensor_frame == base_frame_ ? std::optional<aloam::Pose>(aloam::Pose())
                                                            : lookup(base_frame_, sensor_frame, ros::Time(0));
  if (!base_from_sensor)
  {
    NODELET_WARN_THROTTLE(kThrottleSeconds, "initial pose waits for the transform %s <- %s", base_frame_.c_str(),
                          sensor_frame.c_str());
    return;
  }
  {
    std::lock_guard<std::mutex> lock(correction_mutex_);
    pending_base_pose_.reset();
  }
  // base_link in REP 105's map (base_link at the mapping's start) -> the sensor in the map's own frame.
  useInitialPose(aloam::toBaseFrame(base_from_sensor->inverse(), *base_pose));
}

void LaserLocalizationNodelet::useInitialPose(const aloam::Pose& pose)
{
  NODELET_INFO("initial pose (%.2f, %.2f, %.2f) yaw %.1f deg in %s", pose.t.x(), pose.t.y(), pose.t.z(),
               std::atan2(pose.q.toRotationMatrix()(1, 0), pose.q.toRotationMatrix()(0, 0)) * 180.0 / M_PI,
               outputs_.mapFrame().c_str());
  std::lock_guard<std::mutex> lock(core_mutex_);
  localizer_->setInitialPose(pose);
  ++initial_poses_;
}

void LaserLocalizationNodelet::frameCb(const aloam::ros_io::StampedOdometryFrame::ConstPtr& msg)
{
  aloam::StampAdmission admission;
  {
    std::lock_guard<std::mutex> lock(queue_mutex_);
    admission = admission_.admit(msg->frame, static_cast<std::int64_t>(msg->header.stamp.toNSec()));
    if (!admission.taken)
    {
      if (throttle_.due(admission.verdict))
      {
        NODELET_WARN_STREAM(
            dropMessage(admission.verdict, "laser_odom_frame", msg->header.stamp, admission.step, admission_.counts()));
      }
      return;
    }
  }
  if (admission.reset == aloam::ResetReason::kJumpedBack)
  {
    NODELET_WARN(
        "time jumped back %.3f s (looping bag?): localization starts over in the same map, from the "
        "initial pose of the data's start if one was given",
        -admission.step);
  }
  else if (admission.reset == aloam::ResetReason::kOdometryRestarted)
  {
    NODELET_WARN(
        "odometry started a new trajectory (reset or reloaded): localizing again from the last pose "
        "(%zu so far)",
        admission_.odometryRestarts());
  }
  aloam::Pose corrected;
  bool answered = false;
  {
    std::lock_guard<std::mutex> lock(correction_mutex_);
    if (admission.reset != aloam::ResetReason::kNone)
    {
      // The correction belongs to the old odometry trajectory: no full-rate answer until the localizer has
      // answered in the new one.
      answered_ = false;
    }
    corrected = correction_ * msg->frame.pose;
    answered = answered_;
    sensor_frame_ = msg->sensor_frame_id;
  }
  applyPendingBasePose();
  if (answered)
  {
    outputs_.publishHighRate(msg->header.stamp, corrected, msg->frame.pose, msg->sensor_frame_id);
  }
  if (!map_error_.empty())
  {
    return;
  }
  bool behind = false;
  {
    // Under the lock the worker takes the slot with: no lost wake-up, and the frame and a reset it brought
    // are taken together.
    std::lock_guard<std::mutex> lock(queue_mutex_);
    behind = waiting_.put(msg);
    // Two before the worker got to them: a jump back forgets the pose, which covers an odometry restart.
    if (admission.reset != aloam::ResetReason::kNone && pending_reset_ != aloam::ResetReason::kJumpedBack)
    {
      pending_reset_ = admission.reset;
    }
  }
  if (behind)
  {
    NODELET_WARN_THROTTLE(kThrottleSeconds, "localization is behind: %zu frames skipped so far", waiting_.skipped());
  }
  queue_cv_.notify_one();
}

void LaserLocalizationNodelet::work()
{
  while (!stop_)
  {
    aloam::ros_io::StampedOdometryFrame::ConstPtr msg;
    aloam::ResetReason reset = aloam::ResetReason::kNone;
    {
      std::unique_lock<std::mutex> lock(queue_mutex_);
      queue_cv_.wait(lock, [this] { return stop_ || !waiting_.empty(); });
      if (stop_)
      {
        return;
      }
      msg = *waiting_.take();
      std::swap(reset, pending_reset_);
    }
    const auto start = std::chrono::steady_clock::now();
    aloam::LocalizationResult result;
    {
      std::lock_guard<std::mutex> lock(core_mutex_);
      const aloam::LocalizationState before = localizer_->state();
      localizer_->restart(reset);
      result = localizer_->process(msg->frame);
      last_ = result;
      searches_ += result.searched;
      if (result.searched)
      {
        last_search_ms_ = result.search_ms;
      }
      lost_frames_ += result.state == aloam::LocalizationState::kLost;
      if (result.state != before)
      {
        NODELET_INFO("localization: %s -> %s (inlier share %.2f, mean residual %.3f m)", aloam::toString(before),
                     aloam::toString(result.state), result.fitness.inlier_share, result.fitness.mean_residual);
      }
    }
    if (result.state == aloam::LocalizationState::kLost)
    {
      NODELET_WARN_THROTTLE(kThrottleSeconds,
                            "lost (inlier share %.2f, mean residual %.3f m): publishing the odometry-propagated pose, "
                            "retrying from it",
                            result.fitness.inlier_share, result.fitness.mean_residual);
    }
    if (result.answered)
    {
      {
        std::lock_guard<std::mutex> lock(correction_mutex_);
        correction_ = result.correction;
        answered_ = true;
      }
      outputs_.publishMapped(msg->header.stamp, result.pose, result.correction);
    }
    monitor_.frameDone(msSince(start));
  }
}

}  // namespace aloam_nodelet

PLUGINLIB_EXPORT_CLASS(aloam_nodelet::LaserLocalizationNodelet, nodelet::Nodelet)
