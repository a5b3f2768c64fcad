// Laser odometry nodelet: FeatureSet in, odometry frame out, both as shared pointers.
#include <atomic>
#include <chrono>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <nav_msgs/Odometry.h>
#include <nav_msgs/Path.h>
#include <dynamic_reconfigure/server.h>
#include <nodelet/nodelet.h>
#include <pluginlib/class_list_macros.hpp>
#include <ros/ros.h>
#include <sensor_msgs/PointCloud2.h>
#include <std_srvs/Trigger.h>

#include <aloam_nodelet/LaserOdometryConfig.h>

#include "aloam_nodelet/core/executor.h"
#include "aloam_nodelet/core/laser_odometry.h"
#include "aloam_nodelet/core/sensor_model.h"
#include "aloam_nodelet/ros/conversions.h"
#include "aloam_nodelet/ros/stage_messages.h"
#include "nodelet_common.h"
#include "param_utils.h"
#include "publish_utils.h"
#include "stage_monitor.h"

namespace aloam_nodelet
{
class LaserOdometryNodelet : public nodelet::Nodelet
{
public:
  ~LaserOdometryNodelet() override;

private:
  void onInit() override;
  void featuresCb(const aloam::ros_io::StampedFeatureSet::ConstPtr& msg);
  void mappedCb(const nav_msgs::Odometry::ConstPtr& msg);
  bool process(const aloam::ros_io::StampedFeatureSet::ConstPtr& msg);  // false: sweep dropped
  bool admit(const ros::Time& stamp);  // applies the time policy; false: drop the sweep
  bool resetCb(std_srvs::Trigger::Request& request, std_srvs::Trigger::Response& response);
  void reconfigureCb(const LaserOdometryConfig& config);
  void resetLocked();
  std::vector<double> beamTable(const ros::NodeHandle& pnh) const;

  std::mutex mutex_;                           // guards the core, the path and the time bookkeeping
  std::shared_ptr<aloam::Executor> executor_;  // this nodelet's threads, joined on unload
  std::unique_ptr<aloam::LaserOdometry> odometry_;
  std::string world_frame_, child_frame_;
  std::size_t path_max_poses_ = 10000;
  nav_msgs::Path path_;
  StampGuard stamps_;
  aloam::OdometryFrame last_frame_;  // for diagnostics (clouds not kept)
  std::size_t degraded_frames_ = 0;
  std::size_t remapped_frames_ = 0;
  std::size_t hypotheses_tried_frames_ = 0;  // the prediction looked wrong, other starts were solved
  std::size_t hypotheses_kept_frames_ = 0;   // ... and one of them was kept
  StageMonitor monitor_;

  // Indexing waits for mapping's answer to the frame (aft_mapped_to_init), at most index_wait_: until
  // then mapping, on the latency path, has the cores to itself.
  std::chrono::steady_clock::duration index_wait_{};
  std::atomic<std::uint64_t> awaiting_mapped_ns_{ 0 };  // stamp of the frame whose index waits

  ros::Subscriber features_sub_, mapped_sub_;
  ros::Publisher frame_pub_, odom_pub_, path_pub_, corner_pub_, surf_pub_, full_pub_;
  ros::ServiceServer reset_srv_;
  std::unique_ptr<dynamic_reconfigure::Server<LaserOdometryConfig>> reconfigure_server_;
  // Indexes each sweep for the next one after the frame is out, on the executor's lane; declared last, so
  // stopped (a running index waited for) first.
  aloam::Executor::Job indexer_;
};

LaserOdometryNodelet::~LaserOdometryNodelet()
{
  // The manager's callback threads go on through an unload, so a sweep's callback may still be running here
  // (ThreadSanitizer saw featuresCb request the indexer while the unload destroyed it). Shutting the
  // subscribers down waits for a callback in progress; only then do the indexer and the publishers go.
  features_sub_.shutdown();
  mapped_sub_.shutdown();
}

std::vector<double> LaserOdometryNodelet::beamTable(const ros::NodeHandle& pnh) const
{
  // The same ring model as scan registration's (config/*.yaml sets it in both sections).
  std::string sensor;
  pnh.param<std::string>("sensor", sensor, "");
  const int beams = boundedParam(pnh, getName(), "beams", 0, 0, 256);
  if (beams > 0)
  {
    double min_deg = -15.0, max_deg = 15.0;
    pnh.param("min_elevation_deg", min_deg, min_deg);
    pnh.param("max_elevation_deg", max_deg, max_deg);
    NODELET_INFO("ring neighbourhood through %d beams from %.2f to %.2f deg", beams, min_deg, max_deg);
    return aloam::SensorModel::uniform(beams, min_deg, max_deg).elevationsDeg();
  }
  if (const auto model = aloam::SensorModel::fromPreset(sensor))
  {
    NODELET_INFO("ring neighbourhood through the beam table of %s", sensor.c_str());
    return model->elevationsDeg();
  }
  if (!sensor.empty())
  {
    NODELET_ERROR("unknown sensor preset '%s': the ring neighbourhood counts nearby_scan rings", sensor.c_str());
  }
  else
  {
    NODELET_INFO("no ~sensor: the ring neighbourhood counts nearby_scan rings");
  }
  return {};
}

void LaserOdometryNodelet::onInit()
{
  ros::NodeHandle& nh = getNodeHandle();
  ros::NodeHandle& pnh = getPrivateNodeHandle();
  const std::string& name = getName();

  // Read once at start-up; the rest comes through dynamic_reconfigure (reconfigureCb).
  aloam::LaserOdometryConfig config;
  pnh.param("constant_velocity", config.constant_velocity, config.constant_velocity);
  config.threads = boundedParam(pnh, name, "threads", config.threads, 1, 16);
  config.ring_elevations_deg = beamTable(pnh);
  pnh.param<std::string>("world_frame", world_frame_, "camera_init");
  pnh.param<std::string>("child_frame", child_frame_, "laser_odom");
  path_max_poses_ = static_cast<std::size_t>(boundedParam(pnh, name, "path_max_poses", 10000, 1, 1'000'000));
  executor_ = std::make_shared<aloam::Executor>(config.threads);
  odometry_ = std::make_unique<aloam::LaserOdometry>(config, executor_);
  indexer_ = executor_->makeJob(
      [this]
      {
        std::lock_guard<std::mutex> lock(mutex_);
        odometry_->indexLast();
      });
  path_.header.frame_id = world_frame_;
  stamps_.setConfig(stampCheckParams(pnh, name));
  const double index_wait = boundedParam(pnh, name, "index_wait", 0.5 * stamps_.config().scan_period, 0.0, 1.0);
  index_wait_ =
      std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::duration<double>(index_wait));

  warnOutOfRange<LaserOdometryConfig>(pnh, name);
  reconfigure_server_ = std::make_unique<dynamic_reconfigure::Server<LaserOdometryConfig>>(pnh);
  reconfigure_server_->setCallback([this](LaserOdometryConfig& c, std::uint32_t) { reconfigureCb(c); });

  frame_pub_ = nh.advertise<aloam::ros_io::StampedOdometryFrame>("laser_odom_frame", 2);
  odom_pub_ = nh.advertise<nav_msgs::Odometry>("laser_odom_to_init", 10);
  path_pub_ = nh.advertise<nav_msgs::Path>("laser_odom_path", 2);
  corner_pub_ = nh.advertise<sensor_msgs::PointCloud2>("laser_cloud_corner_last", 2);
  surf_pub_ = nh.advertise<sensor_msgs::PointCloud2>("laser_cloud_surf_last", 2);
  full_pub_ = nh.advertise<sensor_msgs::PointCloud2>("velodyne_cloud_3", 2);
  reset_srv_ = pnh.advertiseService("reset", &LaserOdometryNodelet::resetCb, this);
  monitor_.init(nh, pnh, name,
                [this](diagnostic_updater::DiagnosticStatusWrapper& s)
                {
                  std::lock_guard<std::mutex> lock(mutex_);
                  addMatchDiagnostics(s, last_frame_, degraded_frames_, remapped_frames_);
                  s.add("hypotheses tried (frames)", hypotheses_tried_frames_);
                  s.add("hypotheses kept (frames, another start won)", hypotheses_kept_frames_);
                  s.addf("inlier share", "%.2f", last_frame_.inlier_share);
                  stamps_.report(s);
                  if (last_frame_.status == aloam::OdometryStatus::kDegraded)
                  {
                    s.summary(diagnostic_msgs::DiagnosticStatus::WARN,
                              "degraded: too few or degenerate matches, motion prior used");
                  }
                  else if (last_frame_.status == aloam::OdometryStatus::kRemapped)
                  {
                    s.summary(
                        diagnostic_msgs::DiagnosticStatus::OK,
                        "partially degenerate, remapped: prior kept along " + aloam::describe(last_frame_.degenerate));
                  }
                });
  features_sub_ = nh.subscribe("laser_features", 2, &LaserOdometryNodelet::featuresCb, this);
  if (index_wait_ > std::chrono::steady_clock::duration::zero())
  {
    mapped_sub_ = nh.subscribe("aft_mapped_to_init", 2, &LaserOdometryNodelet::mappedCb, this);
  }
}

void LaserOdometryNodelet::reconfigureCb(const LaserOdometryConfig& c)
{
  std::lock_guard<std::mutex> lock(mutex_);
  aloam::LaserOdometryConfig config = odometry_->config();
  config.max_iterations = c.max_iterations;
  config.outer_iterations = c.outer_iterations;
  config.distance_sq_threshold = c.distance_sq_threshold;
  config.nearby_scan = c.nearby_scan;
  config.deskew = c.deskew;
  config.degeneracy_remap = c.degeneracy_remap;
  config.soft_remap = c.soft_remap;
  config.time_scaling = c.time_scaling;
  config.nearby_elevation_deg = c.nearby_elevation_deg;
  config.motion_hypotheses = c.motion_hypotheses;
  config.hypothesis_min_inlier_share = c.hypothesis_min_inlier_share;
  config.hypothesis_yaw_deg = c.hypothesis_yaw_deg;
  config.hypothesis_translation = c.hypothesis_translation;
  config.hypothesis_outer_iterations = c.hypothesis_outer_iterations;
  config.hypothesis_search_scale = c.hypothesis_search_scale;
  config.hypothesis_min_gain = c.hypothesis_min_gain;
  odometry_->setConfig(config);  // applies from the next sweep
  aloam::StampCheckConfig stamp_config = stamps_.config();
  stamp_config.max_gap_sweeps = c.max_gap_sweeps;
  stamps_.setConfig(stamp_config);
}

void LaserOdometryNodelet::resetLocked()
{
  odometry_->reset();
  path_.poses.clear();
  stamps_.reset();
}

bool LaserOdometryNodelet::resetCb(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& response)
{
  std::lock_guard<std::mutex> lock(mutex_);
  resetLocked();
  response.success = true;
  response.message = "odometry reset: the next sweep starts a new trajectory";
  return true;
}

void LaserOdometryNodelet::featuresCb(const aloam::ros_io::StampedFeatureSet::ConstPtr& msg)
{
  if (!msg->features || malformed(*msg, "laser_features", getName()))
  {
    return;
  }
  const auto start = std::chrono::steady_clock::now();
  if (process(msg))
  {
    monitor_.frameDone(msSince(start));
  }
}

void LaserOdometryNodelet::mappedCb(const nav_msgs::Odometry::ConstPtr& msg)
{
  if (msg->header.stamp.toNSec() == awaiting_mapped_ns_.load())
  {
    indexer_.request();
  }
}

bool LaserOdometryNodelet::admit(const ros::Time& stamp)
{
  const aloam::StampVerdict verdict = stamps_.check(stamp);
  const aloam::StampAction action = aloam::actionFor(verdict);
  if (!action.process)
  {
    if (stamps_.warningDue(verdict))
    {
      NODELET_WARN_STREAM(stamps_.dropMessage(verdict, "laser_features", stamp));
    }
    return false;
  }
  if (action.reset)
  {
    NODELET_WARN("time jumped back %.3f s (looping bag?): odometry reset", -stamps_.lastStep());
    resetLocked();
    stamps_.check(stamp);  // this sweep starts the new run
  }
  if (action.restart_motion)
  {
    if (stamps_.warningDue(verdict))
    {
      NODELET_WARN(
          "%.3f s since the last sweep (more than %.0f periods): motion prior reset, the sweep is "
          "matched from rest (%zu gaps so far)",
          stamps_.lastStep(), stamps_.config().max_gap_sweeps, stamps_.counts().gaps);
    }
    odometry_->resetMotionPrior();
  }
  return true;
}

bool LaserOdometryNodelet::process(const aloam::ros_io::StampedFeatureSet::ConstPtr& msg)
{
  std::lock_guard<std::mutex> lock(mutex_);
  const ros::Time stamp = msg->header.stamp;
  if (!admit(stamp))
  {
    return false;
  }

  auto out = boost::make_shared<aloam::ros_io::StampedOdometryFrame>();
  out->frame = odometry_->track(msg->features);
  out->header.stamp = stamp;
  out->header.frame_id = world_frame_;
  out->child_frame_id = child_frame_;
  out->sensor_frame_id = msg->header.frame_id;
  last_frame_ = out->frame;
  last_frame_.corners.reset();
  last_frame_.surfs.reset();
  last_frame_.full.reset();
  if (out->frame.status == aloam::OdometryStatus::kDegraded)
  {
    ++degraded_frames_;
    NODELET_WARN_THROTTLE(kThrottleSeconds, "odometry degraded (%d edge, %d plane matches, constraint %.1f)",
                          out->frame.corner_matches, out->frame.plane_matches, out->frame.constraint);
  }
  else if (out->frame.status == aloam::OdometryStatus::kRemapped)
  {
    ++remapped_frames_;
    NODELET_DEBUG_THROTTLE(kThrottleSeconds, "odometry partially degenerate, prior kept along %s",
                           aloam::describe(out->frame.degenerate).c_str());
  }
  hypotheses_tried_frames_ += out->frame.hypotheses_tried ? 1 : 0;
  hypotheses_kept_frames_ += out->frame.hypothesis > 0 ? 1 : 0;
  frame_pub_.publish(out);  // never modified after this

  const auto odom =
      boost::make_shared<nav_msgs::Odometry>(aloam::ros_io::toOdometryMsg(out->frame.pose, out->header, child_frame_));
  odom_pub_.publish(odom);
  geometry_msgs::PoseStamped pose;
  pose.header = out->header;
  pose.pose = odom->pose.pose;
  appendAndPublish(path_, pose, path_max_poses_, path_pub_);
  publishCloudIfSubscribed(corner_pub_, *out->frame.corners, msg->header);
  publishCloudIfSubscribed(surf_pub_, *out->frame.surfs, msg->header);
  if (full_pub_.getNumSubscribers() > 0)
  {
    publishCloudIfSubscribed(full_pub_, *aloam::fullAtSweepEnd(out->frame), msg->header);
  }
  // Off the latency path: once mapping has answered for the frame, or after index_wait. (If the next
  // sweep comes first, track() indexes.)
  awaiting_mapped_ns_ = stamp.toNSec();
  indexer_.requestBy(std::chrono::steady_clock::now() + index_wait_);
  return true;
}

}  // namespace aloam_nodelet

PLUGINLIB_EXPORT_CLASS(aloam_nodelet::LaserOdometryNodelet, nodelet::Nodelet)
