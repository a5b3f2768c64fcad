// Publishing helpers shared by the nodelets: no work for nobody, bounded paths.
#pragma once

#include <cstddef>

#include <geometry_msgs/PoseStamped.h>
#include <nav_msgs/Path.h>
#include <ros/publisher.h>
#include <sensor_msgs/PointCloud2.h>

#include "aloam_nodelet/ros/conversions.h"

namespace aloam_nodelet
{
/// Converts and publishes `cloud` only while someone subscribes (visualisation outputs).
inline void publishCloudIfSubscribed(const ros::Publisher& pub, const aloam::Cloud& cloud,
                                     const std_msgs::Header& header)
{
  if (pub.getNumSubscribers() == 0)
  {
    return;
  }
  auto msg = boost::make_shared<sensor_msgs::PointCloud2>();
  aloam::ros_io::toPointCloud2(cloud, header, *msg);
  pub.publish(msg);
}

/// Appends `pose` to `path`, keeping at most `max_poses` (the oldest go), and publishes the path if
/// anyone listens, as a pointer to a copy (in-process subscribers get it without serialization; `path`
/// itself goes on changing).
inline void appendAndPublish(nav_msgs::Path& path, const geometry_msgs::PoseStamped& pose, std::size_t max_poses,
                             const ros::Publisher& pub)
{
  path.poses.push_back(pose);
  if (path.poses.size() > max_poses)
  {
    path.poses.erase(path.poses.begin(), path.poses.begin() + static_cast<long>(path.poses.size() - max_poses));
  }
  if (pub.getNumSubscribers() > 0)
  {
    path.header.stamp = pose.header.stamp;
    pub.publish(boost::make_shared<nav_msgs::Path>(path));
  }
}

}  // namespace aloam_nodelet
