// The stage messages serialize as their generated wire messages and come back equal (what a second
// process or rosbag sees). No master needed.
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>
#include <ros/serialization.h>

#include "aloam_nodelet/core/scan_registration.h"
#include "aloam_nodelet/ros/stage_messages.h"
#include "aloam_nodelet/sim/raycaster.h"
#include "aloam_nodelet/sim/scene.h"

namespace
{
using aloam::ros_io::StampedFeatureSet;
using aloam::ros_io::StampedOdometryFrame;

constexpr double kSensorHeight = 1.8;
constexpr double kStreetX = 40.0;

// One registered VLP16 sweep of the synthetic street.
std::shared_ptr<aloam::FeatureSet> sweepFeatures()
{
  const auto sensor = *aloam::SensorModel::fromPreset("VLP16");
  const auto scene = aloam::sim::Scene::urbanStreet(3, 120.0);
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translation() = Eigen::Vector3d(kStreetX, 0.0, kSensorHeight);
  const aloam::Cloud cloud = aloam::sim::scanStatic(scene, sensor, pose, aloam::sim::ScanOptions{});
  aloam::ScanRegistrationConfig config;
  config.sensor = sensor;
  aloam::ScanRegistration registration(config);
  auto features = std::make_shared<aloam::FeatureSet>();
  EXPECT_TRUE(registration.process(cloud, 0.0, true, true, *features));
  return features;
}

template <typename M>
M roundTrip(const M& in)
{
  const std::uint32_t length = ros::serialization::serializationLength(in);
  std::vector<std::uint8_t> buffer(length);
  ros::serialization::OStream out(buffer.data(), length);
  ros::serialization::serialize(out, in);
  M back;
  ros::serialization::IStream stream(buffer.data(), length);
  ros::serialization::deserialize(stream, back);
  return back;
}

void expectSameCloud(const aloam::Cloud& a, const aloam::Cloud& b, const char* what)
{
  ASSERT_EQ(a.size(), b.size()) << what;
  for (std::size_t i = 0; i < a.size(); ++i)
  {
    ASSERT_EQ(a[i].x, b[i].x) << what << " point " << i;
    ASSERT_EQ(a[i].y, b[i].y) << what << " point " << i;
    ASSERT_EQ(a[i].z, b[i].z) << what << " point " << i;
    ASSERT_EQ(a[i].intensity, b[i].intensity) << what << " point " << i;
    ASSERT_EQ(a[i].ring, b[i].ring) << what << " point " << i;
    // Times are rebased by the reader and restored: equal to float rounding.
    ASSERT_NEAR(a[i].time, b[i].time, 1e-6f) << what << " point " << i;
  }
}

// The in-process types announce the generated messages' type and checksum (rosbag, rostopic, remote nodes).
TEST(StageSerialization, TraitsAreThoseOfTheWireMessages)
{
  using namespace ros::message_traits;
  EXPECT_STREQ(DataType<StampedFeatureSet>::value(), "aloam_nodelet/FeatureClouds");
  EXPECT_STREQ(MD5Sum<StampedFeatureSet>::value(), MD5Sum<aloam_nodelet::FeatureClouds>::value());
  EXPECT_STREQ(DataType<StampedOdometryFrame>::value(), "aloam_nodelet/OdometryFrame");
  EXPECT_STREQ(MD5Sum<StampedOdometryFrame>::value(), MD5Sum<aloam_nodelet::OdometryFrame>::value());
  EXPECT_TRUE(HasHeader<StampedFeatureSet>::value);
}

// A feature set survives serialization: header, flags and every point of every cloud.
TEST(StageSerialization, FeatureSetRoundTrip)
{
  StampedFeatureSet in;
  in.header.stamp = ros::Time(1234, 567890123);
  in.header.frame_id = "velodyne";
  in.header.seq = 42;
  in.features = sweepFeatures();
  const std::size_t conversions = aloam::ros_io::wireConversions();
  const StampedFeatureSet back = roundTrip(in);
  EXPECT_GT(aloam::ros_io::wireConversions(), conversions);

  EXPECT_EQ(back.header.stamp, in.header.stamp);
  EXPECT_EQ(back.header.frame_id, in.header.frame_id);
  ASSERT_TRUE(back.features);
  EXPECT_EQ(back.features->has_time, in.features->has_time);
  EXPECT_DOUBLE_EQ(back.features->scan_period, in.features->scan_period);
  expectSameCloud(in.features->sharp, back.features->sharp, "sharp");
  expectSameCloud(in.features->less_sharp, back.features->less_sharp, "less_sharp");
  expectSameCloud(in.features->flat, back.features->flat, "flat");
  expectSameCloud(in.features->less_flat, back.features->less_flat, "less_flat");
  expectSameCloud(in.features->full, back.features->full, "full");
  ASSERT_TRUE(in.features->bending);
  ASSERT_TRUE(back.features->bending);
  EXPECT_LT(in.features->bending->size(), in.features->less_sharp.size());  // the street has grazing walls too
  expectSameCloud(*in.features->bending, *back.features->bending, "bending");

  // Without the split (curvature_across_ring off, or a publisher that does not fill it) none comes back,
  // and mapping takes less_sharp.
  auto unsplit = std::make_shared<aloam::FeatureSet>(*in.features);
  unsplit->bending.reset();
  in.features = unsplit;
  EXPECT_FALSE(roundTrip(in).features->bending);
}

// An odometry frame survives serialization: poses, status, counters, frames and clouds.
TEST(StageSerialization, OdometryFrameRoundTrip)
{
  const auto features = sweepFeatures();
  StampedOdometryFrame in;
  in.header.stamp = ros::Time(99, 1);
  in.header.frame_id = "camera_init";
  in.child_frame_id = "laser_odom";
  in.sensor_frame_id = "velodyne";
  in.frame.pose = aloam::Pose(Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ())),
                              Eigen::Vector3d(1.0, -2.0, 0.5));
  in.frame.motion = aloam::Pose(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.9, 0.0, 0.0));
  in.frame.status = aloam::OdometryStatus::kDegraded;
  in.frame.distorted = true;
  in.frame.corner_matches = 17;
  in.frame.plane_matches = 230;
  in.frame.constraint = 12.5;
  in.frame.corners = std::shared_ptr<const aloam::Cloud>(features, &features->less_sharp);
  in.frame.surfs = std::shared_ptr<const aloam::Cloud>(features, &features->less_flat);
  in.frame.full = std::shared_ptr<const aloam::Cloud>(features, &features->full);
  const StampedOdometryFrame back = roundTrip(in);

  EXPECT_EQ(back.header.stamp, in.header.stamp);
  EXPECT_EQ(back.child_frame_id, "laser_odom");
  EXPECT_EQ(back.sensor_frame_id, "velodyne");
  EXPECT_NEAR((back.frame.pose.t - in.frame.pose.t).norm(), 0.0, 1e-12);
  EXPECT_NEAR(back.frame.pose.q.angularDistance(in.frame.pose.q), 0.0, 1e-12);
  EXPECT_NEAR((back.frame.motion.t - in.frame.motion.t).norm(), 0.0, 1e-12);
  EXPECT_EQ(back.frame.status, aloam::OdometryStatus::kDegraded);
  EXPECT_TRUE(back.frame.distorted);
  EXPECT_EQ(back.frame.corner_matches, 17);
  EXPECT_EQ(back.frame.plane_matches, 230);
  EXPECT_DOUBLE_EQ(back.frame.constraint, 12.5);
  ASSERT_TRUE(back.frame.corners && back.frame.surfs && back.frame.full);
  expectSameCloud(*in.frame.corners, *back.frame.corners, "corners");
  expectSameCloud(*in.frame.surfs, *back.frame.surfs, "surfs");
  expectSameCloud(*in.frame.full, *back.frame.full, "full");
  EXPECT_TRUE(back.frame.full_motion.isIdentity());

  // A whole sweep still to be deskewed goes on the wire at the sweep end, and comes back with nothing left
  // to do: the same points fullAtSweepEnd gives in process.
  in.frame.full_motion = aloam::Pose(Eigen::Quaterniond(Eigen::AngleAxisd(0.05, Eigen::Vector3d::UnitZ())),
                                     Eigen::Vector3d(1.0, 0.1, 0.0));
  const StampedOdometryFrame moved = roundTrip(in);
  EXPECT_TRUE(moved.frame.full_motion.isIdentity());
  const std::shared_ptr<const aloam::Cloud> at_end = aloam::fullAtSweepEnd(in.frame);
  ASSERT_NE(at_end.get(), in.frame.full.get());
  expectSameCloud(*at_end, *moved.frame.full, "full at the sweep end");
  float moved_most = 0.0f;  // the points taken early in the sweep move by about the whole 1 m
  for (std::size_t i = 0; i < at_end->size(); ++i)
  {
    moved_most = std::max(moved_most, std::hypot(at_end->points[i].x - in.frame.full->points[i].x,
                                                 at_end->points[i].y - in.frame.full->points[i].y));
  }
  EXPECT_GT(moved_most, 0.5f);
}

// Well-formed stage messages pass validate(), as they come from registration and after the wire.
TEST(StageValidation, WellFormedMessagesPass)
{
  StampedFeatureSet features;
  features.features = sweepFeatures();
  EXPECT_EQ(aloam::ros_io::validate(features), "");
  EXPECT_EQ(aloam::ros_io::validate(roundTrip(features)), "");
  StampedOdometryFrame frame;
  frame.frame.corners = std::shared_ptr<const aloam::Cloud>(features.features, &features.features->less_sharp);
  frame.frame.surfs = std::shared_ptr<const aloam::Cloud>(features.features, &features.features->less_flat);
  EXPECT_EQ(aloam::ros_io::validate(frame), "");
  EXPECT_EQ(aloam::ros_io::validate(roundTrip(frame)), "");
}

// Serialized bytes of a message, and those bytes read back as the in-process type.
template <typename Wire>
std::vector<std::uint8_t> bytesOf(const Wire& wire)
{
  std::vector<std::uint8_t> buffer(ros::serialization::serializationLength(wire));
  ros::serialization::OStream out(buffer.data(), static_cast<std::uint32_t>(buffer.size()));
  ros::serialization::serialize(out, wire);
  return buffer;
}
template <typename M>
M fromBytes(std::vector<std::uint8_t> bytes)
{
  M m;
  ros::serialization::IStream in(bytes.data(), static_cast<std::uint32_t>(bytes.size()));
  ros::serialization::deserialize(in, m);
  return m;
}

// Hand-made malformed messages: each is refused, and the refusal says what is wrong.
TEST(StageValidation, MalformedFeatureSetsAreRefused)
{
  const auto good = sweepFeatures();
  auto expectRefused = [](const StampedFeatureSet& m, const std::string& what)
  {
    const std::string error = aloam::ros_io::validate(m);
    EXPECT_NE(error.find(what), std::string::npos) << "expected '" << what << "', got '" << error << "'";
  };
  StampedFeatureSet m;
  expectRefused(m, "no features");

  auto nan_point = std::make_shared<aloam::FeatureSet>(*good);
  nan_point->flat.points[0].y = std::numeric_limits<float>::quiet_NaN();
  m.features = nan_point;
  expectRefused(m, "flat cloud: point 0 not finite");

  // The whole sweep is only displayed: its points are not checked (a NaN there harms nobody).
  auto nan_in_full = std::make_shared<aloam::FeatureSet>(*good);
  nan_in_full->full.points[0].x = std::numeric_limits<float>::quiet_NaN();
  m.features = nan_in_full;
  EXPECT_EQ(aloam::ros_io::validate(m), "");

  auto period = std::make_shared<aloam::FeatureSet>(*good);
  period->scan_period = std::numeric_limits<double>::infinity();
  m.features = period;
  expectRefused(m, "scan_period");

  auto unordered = std::make_shared<aloam::FeatureSet>(*good);
  ASSERT_GT(unordered->less_flat.size(), 2u);
  std::swap(unordered->less_flat.points.front(), unordered->less_flat.points.back());
  m.features = unordered;
  expectRefused(m, "less_flat cloud: not ordered by ring");

  // On the wire: a cloud whose data is shorter than its width says, and a buffer cut short.
  StampedFeatureSet in;
  in.features = good;
  aloam_nodelet::FeatureClouds wire = aloam::ros_io::toWire(in);
  wire.less_sharp.data.resize(wire.less_sharp.data.size() / 2);
  expectRefused(fromBytes<StampedFeatureSet>(bytesOf(wire)), "less_sharp cloud");
  std::vector<std::uint8_t> bytes = bytesOf(aloam::ros_io::toWire(in));
  bytes.resize(bytes.size() - 10);
  EXPECT_THROW(fromBytes<StampedFeatureSet>(bytes), ros::serialization::StreamOverrunException);
}

TEST(StageValidation, MalformedOdometryFramesAreRefused)
{
  const auto features = sweepFeatures();
  StampedOdometryFrame in;
  in.frame.corners = std::shared_ptr<const aloam::Cloud>(features, &features->less_sharp);
  in.frame.surfs = std::shared_ptr<const aloam::Cloud>(features, &features->less_flat);
  auto expectRefused = [](const aloam_nodelet::OdometryFrame& wire, const std::string& what)
  {
    const std::string error = aloam::ros_io::validate(fromBytes<StampedOdometryFrame>(bytesOf(wire)));
    EXPECT_NE(error.find(what), std::string::npos) << "expected '" << what << "', got '" << error << "'";
  };
  aloam_nodelet::OdometryFrame wire = aloam::ros_io::toWire(in);
  wire.pose.orientation.w = 2.0;  // norm 2: no rotation
  expectRefused(wire, "pose: quaternion norm 2");
  wire = aloam::ros_io::toWire(in);
  wire.motion.position.x = std::numeric_limits<double>::infinity();
  expectRefused(wire, "motion: position not finite");
  wire = aloam::ros_io::toWire(in);
  wire.pose.orientation.x = std::numeric_limits<double>::quiet_NaN();
  expectRefused(wire, "pose: quaternion norm nan");
  wire = aloam::ros_io::toWire(in);
  wire.status = 200;
  expectRefused(wire, "unknown status 200");
  wire = aloam::ros_io::toWire(in);
  wire.surfs.width = 1u << 30;  // absurd count for the data it carries
  expectRefused(wire, "surfs cloud");

  StampedOdometryFrame inf_stamp = in;
  inf_stamp.frame.stamp = std::numeric_limits<double>::quiet_NaN();
  EXPECT_NE(aloam::ros_io::validate(inf_stamp).find("stamp not finite"), std::string::npos);
}

}  // namespace
