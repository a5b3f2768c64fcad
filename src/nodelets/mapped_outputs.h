// The outputs of a stage that poses the sensor in the map (mapping, localization), under A-LOAM's names:
// aft_mapped_to_init (one per registered sweep), aft_mapped_to_init_high_frec (one per odometry frame),
// aft_mapped_path, and TF in either of two modes:
//   aloam:  map_frame -> child_frame (camera_init -> aft_mapped), the sensor pose;
//   rep105: map -> odom (the correction) and odom -> base_link (odometry), as REP 105 wants, through the
//           base_link <- sensor extrinsic looked up once.
#pragma once

#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include <nav_msgs/Odometry.h>
#include <nav_msgs/Path.h>
#include <ros/ros.h>
#include <tf2_eigen/tf2_eigen.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_broadcaster.h>
#include <tf2_ros/transform_listener.h>

#include "aloam_nodelet/core/rep105.h"
#include "aloam_nodelet/ros/conversions.h"
#include "nodelet_common.h"
#include "param_utils.h"
#include "publish_utils.h"

namespace aloam_nodelet
{
class MappedOutputs
{
public:
  /// Reads ~map_frame, ~child_frame, ~publish_tf, ~tf_mode, ~rep105_map_frame, ~odom_frame, ~base_frame and
  /// ~path_max_poses, and advertises the topics on `nh`.
  void init(ros::NodeHandle& nh, const ros::NodeHandle& pnh, const std::string& logger)
  {
    logger_ = logger;
    pnh.param<std::string>("map_frame", map_frame_, "camera_init");
    pnh.param<std::string>("child_frame", child_frame_, "aft_mapped");
    pnh.param("publish_tf", publish_tf_, publish_tf_);
    std::string tf_mode = "aloam";
    pnh.param("tf_mode", tf_mode, tf_mode);
    if (tf_mode != "aloam" && tf_mode != "rep105")
    {
      ROS_WARN_NAMED(logger_, "%s: tf_mode '%s' is neither aloam nor rep105; using aloam", logger_.c_str(),
                     tf_mode.c_str());
    }
    rep105_ = tf_mode == "rep105";
    pnh.param<std::string>("rep105_map_frame", rep105_map_frame_, "map");
    pnh.param<std::string>("odom_frame", odom_frame_, "odom");
    pnh.param<std::string>("base_frame", base_frame_, "base_link");
    path_max_poses_ = static_cast<std::size_t>(boundedParam(pnh, logger, "path_max_poses", 10000, 1, 1'000'000));
    path_.header.frame_id = map_frame_;

    tf_broadcaster_ = std::make_unique<tf2_ros::TransformBroadcaster>();
    if (rep105_)
    {
      tf_buffer_ = std::make_unique<tf2_ros::Buffer>();
      tf_listener_ = std::make_unique<tf2_ros::TransformListener>(*tf_buffer_);
    }
    mapped_pub_ = nh.advertise<nav_msgs::Odometry>("aft_mapped_to_init", 10);
    high_rate_pub_ = nh.advertise<nav_msgs::Odometry>("aft_mapped_to_init_high_frec", 10);
    path_pub_ = nh.advertise<nav_msgs::Path>("aft_mapped_path", 2);
  }

  const std::string& mapFrame() const { return map_frame_; }

  /// The full-rate answer to an odometry frame: `corrected` = map <- sensor, `odometry_pose` = odometry's
  /// world <- sensor (REP 105's odom -> base_link), `sensor_frame` the frame of the input clouds.
  void publishHighRate(const ros::Time& stamp, const aloam::Pose& corrected, const aloam::Pose& odometry_pose,
                       const std::string& sensor_frame)
  {
    high_rate_pub_.publish(odometryMsg(corrected, stamp));
    if (rep105_ && publish_tf_)
    {
      if (const auto base_from_sensor = baseFromSensor(sensor_frame))
      {
        tf_broadcaster_->sendTransform(aloam::ros_io::toTransformMsg(
            aloam::toBaseFrame(*base_from_sensor, odometry_pose), header(stamp, odom_frame_), base_frame_));
      }
    }
  }

  /// A registered sweep: `pose` = map <- sensor, `correction` = map <- odometry world.
  void publishMapped(const ros::Time& stamp, const aloam::Pose& pose, const aloam::Pose& correction)
  {
    const nav_msgs::Odometry::Ptr odom = odometryMsg(pose, stamp);
    mapped_pub_.publish(odom);
    if (publish_tf_ && !rep105_)
    {
      tf_broadcaster_->sendTransform(aloam::ros_io::toTransformMsg(pose, odom->header, child_frame_));
    }
    else if (publish_tf_)
    {
      std::optional<aloam::Pose> base_from_sensor;
      {
        std::lock_guard<std::mutex> lock(mutex_);
        base_from_sensor = base_from_sensor_;
      }
      if (base_from_sensor)
      {
        tf_broadcaster_->sendTransform(aloam::ros_io::toTransformMsg(aloam::toBaseFrame(*base_from_sensor, correction),
                                                                     header(stamp, rep105_map_frame_), odom_frame_));
      }
    }
    geometry_msgs::PoseStamped pose_stamped;
    pose_stamped.header = odom->header;
    pose_stamped.pose = odom->pose.pose;
    std::lock_guard<std::mutex> lock(mutex_);
    appendAndPublish(path_, pose_stamped, path_max_poses_, path_pub_);
  }

  /// Replaces the path by these poses (map <- sensor), the newest path_max_poses of them (a loop closed).
  void replacePath(const std::vector<aloam::Pose>& poses, const std::vector<double>& stamps)
  {
    std::lock_guard<std::mutex> lock(mutex_);
    path_.poses.clear();
    const std::size_t first = poses.size() > path_max_poses_ ? poses.size() - path_max_poses_ : 0;
    for (std::size_t i = first; i < poses.size(); ++i)
    {
      ros::Time stamp;
      stamp.fromSec(stamps[i]);
      const nav_msgs::Odometry::Ptr odom = odometryMsg(poses[i], stamp);
      geometry_msgs::PoseStamped p;
      p.header = odom->header;
      p.pose = odom->pose.pose;
      path_.poses.push_back(p);
    }
    if (!path_.poses.empty() && path_pub_.getNumSubscribers() > 0)
    {
      path_.header.stamp = path_.poses.back().header.stamp;
      path_pub_.publish(boost::make_shared<nav_msgs::Path>(path_));
    }
  }

  /// Forgets the path (a new map).
  void clearPath()
  {
    std::lock_guard<std::mutex> lock(mutex_);
    path_.poses.clear();
  }

private:
  std_msgs::Header header(const ros::Time& stamp, const std::string& frame) const
  {
    std_msgs::Header h;
    h.stamp = stamp;
    h.frame_id = frame;
    return h;
  }

  nav_msgs::Odometry::Ptr odometryMsg(const aloam::Pose& pose, const ros::Time& stamp) const
  {
    return boost::make_shared<nav_msgs::Odometry>(
        aloam::ros_io::toOdometryMsg(pose, header(stamp, map_frame_), child_frame_));
  }

  std::optional<aloam::Pose> baseFromSensor(const std::string& sensor_frame)
  {
    {
      std::lock_guard<std::mutex> lock(mutex_);
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
        const geometry_msgs::TransformStamped t = tf_buffer_->lookupTransform(base_frame_, sensor_frame, ros::Time(0));
        extrinsic = aloam::Pose(tf2::transformToEigen(t));
      }
      catch (const tf2::TransformException& e)
      {
        ROS_WARN_THROTTLE_NAMED(kThrottleSeconds, logger_, "%s: rep105: no transform %s <- %s yet (%s)",
                                logger_.c_str(), base_frame_.c_str(), sensor_frame.c_str(), e.what());
        return std::nullopt;
      }
    }
    std::lock_guard<std::mutex> lock(mutex_);
    base_from_sensor_ = extrinsic;
    return base_from_sensor_;
  }

  std::string logger_;
  std::string map_frame_, child_frame_;
  bool publish_tf_ = true;
  bool rep105_ = false;
  std::string rep105_map_frame_, odom_frame_, base_frame_;
  std::size_t path_max_poses_ = 10000;

  std::mutex mutex_;  // the path and the extrinsic: the two answers come from different threads
  nav_msgs::Path path_;
  std::optional<aloam::Pose> base_from_sensor_;

  ros::Publisher mapped_pub_, high_rate_pub_, path_pub_;
  std::unique_ptr<tf2_ros::TransformBroadcaster> tf_broadcaster_;
  std::unique_ptr<tf2_ros::Buffer> tf_buffer_;
  std::unique_ptr<tf2_ros::TransformListener> tf_listener_;
};

}  // namespace aloam_nodelet
