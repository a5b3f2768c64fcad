// The messages between the nodelets: in one manager they travel as shared pointers to the core's own
// types (no copy, no serialization); across processes, machines and rosbag they serialize as the
// generated aloam_nodelet/FeatureClouds and aloam_nodelet/OdometryFrame messages (as pcl_ros does for
// pcl::PointCloud).
#pragma once

#include <memory>
#include <string>

#include <boost/shared_ptr.hpp>
#include <ros/message_traits.h>
#include <ros/serialization.h>
#include <std_msgs/Header.h>

#include <aloam_nodelet/FeatureClouds.h>
#include <aloam_nodelet/OdometryFrame.h>

#include "aloam_nodelet/core/feature_set.h"
#include "aloam_nodelet/core/laser_odometry.h"

namespace aloam
{
namespace ros_io
{
/// Registration -> odometry: one sweep's features. `features` is never modified after publishing.
struct StampedFeatureSet
{
  std_msgs::Header header;  ///< the input sweep's stamp and frame
  std::shared_ptr<const FeatureSet> features;
  /// Why fromWire() could not take the message as it came (empty: it could); see validate().
  std::string wire_error;

  using Ptr = boost::shared_ptr<StampedFeatureSet>;
  using ConstPtr = boost::shared_ptr<const StampedFeatureSet>;
};

/// Odometry -> mapping: one sweep's odometry pose and the clouds mapping needs.
struct StampedOdometryFrame
{
  std_msgs::Header header;      ///< the sweep's stamp; frame_id is the odometry world frame
  std::string child_frame_id;   ///< the odometry body frame
  std::string sensor_frame_id;  ///< frame of the input point clouds
  OdometryFrame frame;
  /// Why fromWire() could not take the message as it came (empty: it could); see validate().
  std::string wire_error;

  using Ptr = boost::shared_ptr<StampedOdometryFrame>;
  using ConstPtr = boost::shared_ptr<const StampedOdometryFrame>;
};

/// How many stage messages this process has converted to their wire form (i.e. serialized) so far: 0 while
/// every subscriber lives in the same nodelet manager.
std::size_t wireConversions();

/// Conversions to and from the wire messages (used only when a message is serialized).
aloam_nodelet::FeatureClouds toWire(const StampedFeatureSet& in);
void fromWire(const aloam_nodelet::FeatureClouds& in, StampedFeatureSet& out);
aloam_nodelet::OdometryFrame toWire(const StampedOdometryFrame& in);
void fromWire(const aloam_nodelet::OdometryFrame& in, StampedOdometryFrame& out);

/// Whether every length prefix of a serialized FeatureClouds / OdometryFrame (strings, cloud fields, cloud
/// data) fits in the bytes that follow. roscpp's generated readers resize a vector to its prefix before
/// they read it, so a message claiming 4 G cloud fields would allocate ~100 GB before failing.
bool wireLengthsFit(const aloam_nodelet::FeatureClouds* type, const std::uint8_t* data, std::uint32_t size);
bool wireLengthsFit(const aloam_nodelet::OdometryFrame* type, const std::uint8_t* data, std::uint32_t size);

/// Whether a stage message (from another process, a bag, or this one) is fit for the next stage: empty if
/// it is, else why not (unreadable or truncated clouds, NaN/Inf points, poses or stamps, a non-unit
/// quaternion, an absurd scan period or point count, clouds not ordered by ring). The whole sweep (`full`),
/// which no stage computes with and which is only displayed, is checked by its size alone. Both the
/// nodelets and test/fuzz/fuzz_stage_messages.cpp call it before handing the message to the core.
std::string validate(const StampedFeatureSet& msg);
std::string validate(const StampedOdometryFrame& msg);

/// More points than this in one stage cloud is no sweep (the input reader caps a sweep at 20 M points).
constexpr std::size_t kMaxStagePoints = 20'000'000;
/// Stage clouds are in the sensor frame: a point farther than this (m) along an axis is no return (the
/// widest range a .cfg allows is 500 m), and squaring such coordinates could overflow in the stages.
constexpr float kMaxStageRange = 10'000.0f;
/// Poses farther than this (m) from the odometry origin: 10,000 km, no drive gets there.
constexpr double kMaxStageTranslation = 1e7;

}  // namespace ros_io
}  // namespace aloam

namespace ros
{
namespace message_traits
{
// Traits of an in-process type: those of the generated message `Wire` it serializes as.
#define ALOAM_STAGE_MESSAGE_TRAITS(T, Wire)                          \
  template <>                                                        \
  struct MD5Sum<T>                                                   \
  {                                                                  \
    static const char* value() { return MD5Sum<Wire>::value(); }     \
    static const char* value(const T&) { return value(); }           \
  };                                                                 \
  template <>                                                        \
  struct DataType<T>                                                 \
  {                                                                  \
    static const char* value() { return DataType<Wire>::value(); }   \
    static const char* value(const T&) { return value(); }           \
  };                                                                 \
  template <>                                                        \
  struct Definition<T>                                               \
  {                                                                  \
    static const char* value() { return Definition<Wire>::value(); } \
    static const char* value(const T&) { return value(); }           \
  };                                                                 \
  template <>                                                        \
  struct HasHeader<T> : TrueType                                     \
  {                                                                  \
  };

ALOAM_STAGE_MESSAGE_TRAITS(aloam::ros_io::StampedFeatureSet, aloam_nodelet::FeatureClouds)
ALOAM_STAGE_MESSAGE_TRAITS(aloam::ros_io::StampedOdometryFrame, aloam_nodelet::OdometryFrame)
#undef ALOAM_STAGE_MESSAGE_TRAITS

}  // namespace message_traits

namespace serialization
{
/// Serializes an in-process stage message through its wire message.
template <typename T>
struct StageSerializer
{
  template <typename Stream>
  static void write(Stream& stream, const T& m)
  {
    stream.next(aloam::ros_io::toWire(m));
  }

  template <typename Stream>
  static void read(Stream& stream, T& m)
  {
    decltype(aloam::ros_io::toWire(m)) wire;
    if (!aloam::ros_io::wireLengthsFit(&wire, stream.getData(), stream.getLength()))
    {
      throw StreamOverrunException("stage message: a length prefix runs past the end of the buffer");
    }
    stream.next(wire);
    aloam::ros_io::fromWire(wire, m);
  }

  static std::uint32_t serializedLength(const T& m) { return serializationLength(aloam::ros_io::toWire(m)); }
};

template <>
struct Serializer<aloam::ros_io::StampedFeatureSet> : StageSerializer<aloam::ros_io::StampedFeatureSet>
{
};
template <>
struct Serializer<aloam::ros_io::StampedOdometryFrame> : StageSerializer<aloam::ros_io::StampedOdometryFrame>
{
};

}  // namespace serialization
}  // namespace ros
