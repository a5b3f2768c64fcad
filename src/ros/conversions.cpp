#include "aloam_nodelet/ros/conversions.h"

#include <pcl_conversions/pcl_conversions.h>

namespace aloam
{
namespace ros_io
{
geometry_msgs::Pose toPoseMsg(const Pose& pose)
{
  geometry_msgs::Pose msg;
  const Eigen::Quaterniond q = pose.q.normalized();
  msg.position.x = pose.t.x();
  msg.position.y = pose.t.y();
  msg.position.z = pose.t.z();
  msg.orientation.x = q.x();
  msg.orientation.y = q.y();
  msg.orientation.z = q.z();
  msg.orientation.w = q.w();
  return msg;
}

Pose fromPoseMsg(const geometry_msgs::Pose& msg)
{
  Eigen::Quaterniond q(msg.orientation.w, msg.orientation.x, msg.orientation.y, msg.orientation.z);
  if (!(q.norm() > 0.0))
  {
    q = Eigen::Quaterniond::Identity();
  }
  return Pose(q.normalized(), Eigen::Vector3d(msg.position.x, msg.position.y, msg.position.z));
}

nav_msgs::Odometry toOdometryMsg(const Pose& pose, const std_msgs::Header& header, const std::string& child_frame_id)
{
  nav_msgs::Odometry msg;
  msg.header = header;
  msg.child_frame_id = child_frame_id;
  msg.pose.pose = toPoseMsg(pose);
  return msg;
}

geometry_msgs::TransformStamped toTransformMsg(const Pose& pose, const std_msgs::Header& header,
                                               const std::string& child_frame_id)
{
  geometry_msgs::TransformStamped msg;
  msg.header = header;
  msg.child_frame_id = child_frame_id;
  const geometry_msgs::Pose p = toPoseMsg(pose);
  msg.transform.translation.x = p.position.x;
  msg.transform.translation.y = p.position.y;
  msg.transform.translation.z = p.position.z;
  msg.transform.rotation = p.orientation;
  return msg;
}

void toPointCloud2(const Cloud& cloud, const std_msgs::Header& header, sensor_msgs::PointCloud2& out)
{
  pcl::toROSMsg(cloud, out);
  out.header = header;
}

}  // namespace ros_io
}  // namespace aloam
