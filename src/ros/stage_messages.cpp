#include "aloam_nodelet/ros/stage_messages.h"

#include <atomic>

#include "aloam_nodelet/ros/conversions.h"
#include "aloam_nodelet/ros/pointcloud2_reader.h"

namespace aloam
{
namespace ros_io
{
namespace
{
// Statistics only: counts serializations so that tests and diagnostics can see whether any happened.
std::atomic<std::size_t> wire_conversions{ 0 };

// Reads a cloud written by toPointCloud2 (fields x y z intensity time ring), keeping its times as they
// were (the reader makes them relative to the earliest point).
void readCloud(const sensor_msgs::PointCloud2& msg, Cloud& out)
{
  ReaderOptions options;
  options.max_points = 0;  // written by us: no cap
  const ReadReport report = readPointCloud2(msg, options, out);
  if (!report.ok)
  {
    out.clear();
    return;
  }
  const float origin = static_cast<float>(report.time_origin);
  for (Point& p : out.points)
  {
    p.time += origin;
  }
}

std::shared_ptr<const Cloud> readSharedCloud(const sensor_msgs::PointCloud2& msg)
{
  auto cloud = std::make_shared<Cloud>();
  readCloud(msg, *cloud);
  return cloud;
}

void writeCloud(const std::shared_ptr<const Cloud>& cloud, const std_msgs::Header& header,
                sensor_msgs::PointCloud2& out)
{
  toPointCloud2(cloud ? *cloud : Cloud(), header, out);
}
}  // namespace

std::size_t wireConversions()
{
  return wire_conversions.load();
}

aloam_nodelet::FeatureClouds toWire(const StampedFeatureSet& in)
{
  ++wire_conversions;
  aloam_nodelet::FeatureClouds out;
  out.header = in.header;
  if (!in.features)
  {
    return out;
  }
  const FeatureSet& f = *in.features;
  out.scan_period = f.scan_period;
  out.has_time = f.has_time;
  toPointCloud2(f.sharp, in.header, out.sharp);
  toPointCloud2(f.less_sharp, in.header, out.less_sharp);
  toPointCloud2(f.flat, in.header, out.flat);
  toPointCloud2(f.less_flat, in.header, out.less_flat);
  toPointCloud2(f.full, in.header, out.full);
  return out;
}

void fromWire(const aloam_nodelet::FeatureClouds& in, StampedFeatureSet& out)
{
  auto f = std::make_shared<FeatureSet>();
  f->stamp = in.header.stamp.toSec();
  f->scan_period = in.scan_period;
  f->has_time = in.has_time;
  readCloud(in.sharp, f->sharp);
  readCloud(in.less_sharp, f->less_sharp);
  readCloud(in.flat, f->flat);
  readCloud(in.less_flat, f->less_flat);
  readCloud(in.full, f->full);
  out.header = in.header;
  out.features = f;
}

aloam_nodelet::OdometryFrame toWire(const StampedOdometryFrame& in)
{
  ++wire_conversions;
  aloam_nodelet::OdometryFrame out;
  out.header = in.header;
  out.child_frame_id = in.child_frame_id;
  out.sensor_frame_id = in.sensor_frame_id;
  const OdometryFrame& f = in.frame;
  out.pose = toPoseMsg(f.pose);
  out.motion = toPoseMsg(f.motion);
  out.status = static_cast<std::uint8_t>(f.status);
  out.distorted = f.distorted;
  out.corner_matches = f.corner_matches;
  out.plane_matches = f.plane_matches;
  out.constraint = f.constraint;
  out.degenerate_directions = static_cast<std::uint8_t>(f.degenerate.size());
  writeCloud(f.corners, in.header, out.corners);
  writeCloud(f.surfs, in.header, out.surfs);
  writeCloud(f.full, in.header, out.full);
  return out;
}

void fromWire(const aloam_nodelet::OdometryFrame& in, StampedOdometryFrame& out)
{
  out.header = in.header;
  out.child_frame_id = in.child_frame_id;
  out.sensor_frame_id = in.sensor_frame_id;
  OdometryFrame& f = out.frame;
  f.stamp = in.header.stamp.toSec();
  f.pose = fromPoseMsg(in.pose);
  f.motion = fromPoseMsg(in.motion);
  f.status = in.status <= static_cast<std::uint8_t>(OdometryStatus::kRemapped) ? static_cast<OdometryStatus>(in.status)
                                                                               : OdometryStatus::kDegraded;
  f.distorted = in.distorted;
  f.corner_matches = in.corner_matches;
  f.plane_matches = in.plane_matches;
  f.constraint = in.constraint;
  f.corners = readSharedCloud(in.corners);
  f.surfs = readSharedCloud(in.surfs);
  f.full = readSharedCloud(in.full);
}

}  // namespace ros_io
}  // namespace aloam
