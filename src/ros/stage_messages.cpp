#include "aloam_nodelet/ros/stage_messages.h"

#include <atomic>
#include <cmath>
#include <cstring>
#include <sstream>
#include <tuple>
#include <utility>

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
// were (the reader makes them relative to the earliest point). A cloud that cannot be read whole is
// cleared and `error` (if still empty) says why.
void readCloud(const sensor_msgs::PointCloud2& msg, Cloud& out, const char* name, std::string& error)
{
  ReaderOptions options;
  options.max_points = kMaxStagePoints;
  const ReadReport report = readPointCloud2(msg, options, out);
  const bool empty_message = msg.width == 0 || msg.height == 0;  // an empty cloud (no fields either) is fine
  const bool short_read = report.points_out + report.dropped_invalid < report.points_in;
  if (!report.ok || (!empty_message && (report.dropped_invalid > 0 || short_read)))
  {
    if (error.empty() && !empty_message)
    {
      error = std::string(name) + " cloud: " +
              (!report.ok   ? report.error
               : short_read ? "truncated data"
                            : "NaN/Inf or all-zero points");
    }
    out.clear();
    return;
  }
  const float origin = static_cast<float>(report.time_origin);
  for (Point& p : out.points)
  {
    p.time += origin;
  }
}

std::shared_ptr<const Cloud> readSharedCloud(const sensor_msgs::PointCloud2& msg, const char* name, std::string& error)
{
  auto cloud = std::make_shared<Cloud>();
  readCloud(msg, *cloud, name, error);
  return cloud;
}

// fromPoseMsg() normalizes the quaternion: a pose that needed more than rounding is refused here.
void checkPose(const geometry_msgs::Pose& pose, const char* name, std::string& error)
{
  const auto& q = pose.orientation;
  const double norm = std::sqrt(q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z);
  const auto& t = pose.position;
  if (error.empty() && !(std::isfinite(t.x) && std::isfinite(t.y) && std::isfinite(t.z)))
  {
    error = std::string(name) + ": position not finite";
  }
  if (error.empty() && !(std::abs(norm - 1.0) < 1e-3))
  {
    std::ostringstream s;
    s << name << ": quaternion norm " << norm << " (not a rotation)";
    error = s.str();
  }
}

// Reads through a serialized message, checking each length prefix against what is left.
class WireCursor
{
public:
  WireCursor(const std::uint8_t* data, std::uint32_t size) : data_(data), left_(data == nullptr ? 0 : size) {}

  bool skip(std::uint32_t n)
  {
    if (n > left_)
    {
      return false;
    }
    data_ += n;
    left_ -= n;
    return true;
  }
  bool u32(std::uint32_t& v)
  {
    if (left_ < 4)
    {
      return false;
    }
    std::memcpy(&v, data_, 4);  // ROS serializes little-endian, as this machine
    return skip(4);
  }
  bool string()
  {
    std::uint32_t n = 0;
    return u32(n) && skip(n);
  }
  bool header() { return skip(4 + 8) && string(); }  // seq, stamp, frame_id
  bool cloud()
  {
    std::uint32_t fields = 0, bytes = 0;
    if (!header() || !skip(4 + 4) || !u32(fields) || fields > left_ / 13)  // height, width; a field is >= 13 bytes
    {
      return false;
    }
    for (std::uint32_t i = 0; i < fields; ++i)
    {
      if (!string() || !skip(4 + 1 + 4))  // name, offset, datatype, count
      {
        return false;
      }
    }
    return skip(1 + 4 + 4) && u32(bytes) && skip(bytes) && skip(1);  // is_bigendian, steps, data, is_dense
  }

private:
  const std::uint8_t* data_;
  std::uint32_t left_;
};

// The whole sweep (`full`) is carried for display only: no stage computes with its points, a NaN in a
// displayed cloud is common in ROS, and checking its points was most of the time from registration to
// odometry (docs/performance.md). Only its size is checked.
std::string checkSize(const Cloud* cloud, const char* name)
{
  if (cloud != nullptr && cloud->size() > kMaxStagePoints)
  {
    return std::string(name) + " cloud: " + std::to_string(cloud->size()) + " points";
  }
  return "";
}

std::string checkCloud(const Cloud* cloud, const char* name, bool by_ring)
{
  if (cloud == nullptr)
  {
    return "";  // a stage without that cloud copes (mapping downsamples only the clouds it has)
  }
  if (std::string error = checkSize(cloud, name); !error.empty())
  {
    return error;
  }
  for (std::size_t i = 0; i < cloud->size(); ++i)
  {
    const Point& p = cloud->points[i];
    if (!(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z) && std::isfinite(p.time)))
    {
      return std::string(name) + " cloud: point " + std::to_string(i) + " not finite";
    }
    if (!(std::abs(p.x) <= kMaxStageRange && std::abs(p.y) <= kMaxStageRange && std::abs(p.z) <= kMaxStageRange))
    {
      return std::string(name) + " cloud: point " + std::to_string(i) + " farther than " +
             std::to_string(int(kMaxStageRange)) + " m";
    }
    if (by_ring && i > 0 && p.ring < cloud->points[i - 1].ring)
    {
      return std::string(name) + " cloud: not ordered by ring at point " + std::to_string(i);
    }
  }
  return "";
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
  if (f.bending)
  {
    toPointCloud2(*f.bending, in.header, out.bending);
  }
  return out;
}

void fromWire(const aloam_nodelet::FeatureClouds& in, StampedFeatureSet& out)
{
  auto f = std::make_shared<FeatureSet>();
  f->stamp = in.header.stamp.toSec();
  f->scan_period = in.scan_period;
  f->has_time = in.has_time;
  out.wire_error.clear();
  readCloud(in.sharp, f->sharp, "sharp", out.wire_error);
  readCloud(in.less_sharp, f->less_sharp, "less_sharp", out.wire_error);
  readCloud(in.flat, f->flat, "flat", out.wire_error);
  readCloud(in.less_flat, f->less_flat, "less_flat", out.wire_error);
  readCloud(in.full, f->full, "full", out.wire_error);
  // A cloud without fields was never filled (a publisher that does not tell the edges apart).
  if (!in.bending.fields.empty())
  {
    readCloud(in.bending, f->bending.emplace(), "bending", out.wire_error);
  }
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
  writeCloud(fullAtSweepEnd(f), in.header, out.full);  // at the sweep end on the wire
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
  out.wire_error.clear();
  checkPose(in.pose, "pose", out.wire_error);
  checkPose(in.motion, "motion", out.wire_error);
  if (out.wire_error.empty() && in.status > static_cast<std::uint8_t>(OdometryStatus::kRemapped))
  {
    out.wire_error = "unknown status " + std::to_string(in.status);
  }
  f.corners = readSharedCloud(in.corners, "corners", out.wire_error);
  f.surfs = readSharedCloud(in.surfs, "surfs", out.wire_error);
  f.full = readSharedCloud(in.full, "full", out.wire_error);
  f.full_motion = Pose();  // the wire carries it at the sweep end
}

bool wireLengthsFit(const aloam_nodelet::FeatureClouds*, const std::uint8_t* data, std::uint32_t size)
{
  WireCursor c(data, size);
  return c.header() && c.skip(8 + 1) && c.cloud() && c.cloud() && c.cloud() && c.cloud() && c.cloud();
}

bool wireLengthsFit(const aloam_nodelet::OdometryFrame*, const std::uint8_t* data, std::uint32_t size)
{
  WireCursor c(data, size);
  // header, frames, two poses (7 float64 each), status, distorted, matches, constraint, degenerate count
  return c.header() && c.string() && c.string() && c.skip(2 * 56 + 1 + 1 + 4 + 4 + 8 + 1) && c.cloud() && c.cloud() &&
         c.cloud();
}

std::string validate(const StampedFeatureSet& msg)
{
  if (!msg.wire_error.empty())
  {
    return msg.wire_error;
  }
  if (!msg.features)
  {
    return "no features";
  }
  const FeatureSet& f = *msg.features;
  if (!std::isfinite(f.stamp))
  {
    return "stamp not finite";
  }
  if (!(f.scan_period > 0.0 && f.scan_period <= 10.0))
  {
    return "scan_period " + std::to_string(f.scan_period) + " s outside (0, 10]";
  }
  // Odometry indexes the edge and plane clouds ring by ring; the others it only reads.
  for (const auto& [cloud, name, by_ring] :
       { std::make_tuple(&f.sharp, "sharp", false), std::make_tuple(&f.less_sharp, "less_sharp", true),
         std::make_tuple(&f.flat, "flat", false), std::make_tuple(&f.less_flat, "less_flat", true),
         std::make_tuple(f.bending ? &*f.bending : nullptr, "bending", false) })
  {
    const std::string error = checkCloud(cloud, name, by_ring);
    if (!error.empty())
    {
      return error;
    }
  }
  return checkSize(&f.full, "full");
}

std::string validate(const StampedOdometryFrame& msg)
{
  if (!msg.wire_error.empty())
  {
    return msg.wire_error;
  }
  const OdometryFrame& f = msg.frame;
  if (!std::isfinite(f.stamp))
  {
    return "stamp not finite";
  }
  for (const auto& [pose, name] : { std::make_pair(&f.pose, "pose"), std::make_pair(&f.motion, "motion") })
  {
    if (!pose->isFinite() || !(std::abs(pose->q.norm() - 1.0) < 1e-3) || !(pose->t.norm() <= kMaxStageTranslation))
    {
      return std::string(name) + " not a rigid transform within " + std::to_string(int(kMaxStageTranslation)) + " m";
    }
  }
  for (const auto& [cloud, name] :
       { std::make_pair(f.corners.get(), "corners"), std::make_pair(f.surfs.get(), "surfs") })
  {
    const std::string error = checkCloud(cloud, name, false);
    if (!error.empty())
    {
      return error;
    }
  }
  return checkSize(f.full.get(), "full");
}

}  // namespace ros_io
}  // namespace aloam
