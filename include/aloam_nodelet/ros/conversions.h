// Conversions between the core's types and ROS messages.
#pragma once

#include <geometry_msgs/Pose.h>
#include <geometry_msgs/TransformStamped.h>
#include <nav_msgs/Odometry.h>
#include <sensor_msgs/PointCloud2.h>
#include <std_msgs/Header.h>

#include "aloam_nodelet/core/pose.h"

namespace aloam
{
namespace ros_io
{
geometry_msgs::Pose toPoseMsg(const Pose& pose);
Pose fromPoseMsg(const geometry_msgs::Pose& msg);

/// An Odometry message carrying `pose` (header.frame_id <- child_frame_id).
nav_msgs::Odometry toOdometryMsg(const Pose& pose, const std_msgs::Header& header, const std::string& child_frame_id);

/// The transform header.frame_id <- child_frame_id given by `pose`.
geometry_msgs::TransformStamped toTransformMsg(const Pose& pose, const std_msgs::Header& header,
                                               const std::string& child_frame_id);

/// Writes `cloud` as a PointCloud2 with fields x y z intensity time ring.
void toPointCloud2(const Cloud& cloud, const std_msgs::Header& header, sensor_msgs::PointCloud2& out);

}  // namespace ros_io
}  // namespace aloam
