// Zero-copy between the stages: registration and odometry loaded into this process's nodelet loader
// (one manager), this test subscribing in the same process. The feature set odometry matched is the
// very object registration published, and nothing is serialized while no one outside subscribes.
#include <condition_variable>
#include <map>
#include <mutex>

#include <gtest/gtest.h>
#include <nodelet/loader.h>
#include <ros/ros.h>
#include <sensor_msgs/PointCloud2.h>

#include "aloam_nodelet/ros/conversions.h"
#include "aloam_nodelet/ros/stage_messages.h"
#include "aloam_nodelet/sim/raycaster.h"
#include "aloam_nodelet/sim/scene.h"

namespace
{
using aloam::ros_io::StampedFeatureSet;
using aloam::ros_io::StampedOdometryFrame;

constexpr int kSweeps = 5;
constexpr double kTimeout = 20.0;  // s for all sweeps to come through
constexpr double kSpeed = 10.0;    // m/s along the synthetic street

class Collector
{
public:
  void features(const StampedFeatureSet::ConstPtr& m)
  {
    std::lock_guard<std::mutex> lock(mutex_);
    features_[m->header.stamp] = m;
    cv_.notify_all();
  }
  void frame(const StampedOdometryFrame::ConstPtr& m)
  {
    std::lock_guard<std::mutex> lock(mutex_);
    frames_[m->header.stamp] = m;
    cv_.notify_all();
  }
  bool waitFor(std::size_t n)
  {
    std::unique_lock<std::mutex> lock(mutex_);
    return cv_.wait_for(lock, std::chrono::duration<double>(kTimeout),
                        [&] { return features_.size() >= n && frames_.size() >= n; });
  }
  std::mutex mutex_;
  std::condition_variable cv_;
  std::map<ros::Time, StampedFeatureSet::ConstPtr> features_;
  std::map<ros::Time, StampedOdometryFrame::ConstPtr> frames_;
};

TEST(ZeroCopy, StagesShareObjectsInOneManager)
{
  ros::NodeHandle nh;
  nodelet::Loader loader(false);
  ASSERT_TRUE(loader.load("/scan_registration", "aloam_nodelet/ScanRegistration", {}, {}));
  ASSERT_TRUE(loader.load("/laser_odometry", "aloam_nodelet/LaserOdometry", {}, {}));

  Collector collector;
  ros::Subscriber features_sub = nh.subscribe("laser_features", 10, &Collector::features, &collector);
  ros::Subscriber frames_sub = nh.subscribe("laser_odom_frame", 10, &Collector::frame, &collector);
  ros::Publisher points_pub = nh.advertise<sensor_msgs::PointCloud2>("velodyne_points", 1);
  ros::AsyncSpinner spinner(1);
  spinner.start();
  for (int i = 0; i < 50 && points_pub.getNumSubscribers() == 0; ++i)
  {
    ros::Duration(0.1).sleep();
  }
  ASSERT_GT(points_pub.getNumSubscribers(), 0u);

  const std::size_t conversions_before = aloam::ros_io::wireConversions();
  const auto sensor = *aloam::SensorModel::fromPreset("VLP16");
  const auto scene = aloam::sim::Scene::urbanStreet(5, 150.0);
  for (int k = 0; k < kSweeps; ++k)
  {
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.translation() = Eigen::Vector3d(30.0 + kSpeed * 0.1 * k, 0.0, 1.8);
    const aloam::Cloud cloud = aloam::sim::scanStatic(scene, sensor, pose, aloam::sim::ScanOptions{});
    auto msg = boost::make_shared<sensor_msgs::PointCloud2>();
    std_msgs::Header header;
    header.stamp = ros::Time(100.0 + 0.1 * k);
    header.frame_id = "velodyne";
    aloam::ros_io::toPointCloud2(cloud, header, *msg);
    points_pub.publish(msg);
    // One sweep at a time: registration keeps only the newest (queue of one).
    std::unique_lock<std::mutex> lock(collector.mutex_);
    ASSERT_TRUE(collector.cv_.wait_for(lock, std::chrono::duration<double>(kTimeout),
                                       [&] { return collector.frames_.count(header.stamp) > 0; }))
        << "sweep " << k << " not answered";
  }
  ASSERT_TRUE(collector.waitFor(kSweeps));

  std::lock_guard<std::mutex> lock(collector.mutex_);
  for (const auto& [stamp, frame] : collector.frames_)
  {
    const auto features = collector.features_.at(stamp);
    ASSERT_TRUE(features->features);
    // Odometry's clouds alias the feature set it received: the same object this test received, hence
    // the object registration published (a deserialized copy would live elsewhere).
    ASSERT_TRUE(features->features->bending) << "stamp " << stamp;  // curvature_across_ring is on by default
    EXPECT_EQ(frame->frame.corners.get(), &*features->features->bending) << "stamp " << stamp;
    EXPECT_EQ(frame->frame.surfs.get(), &features->features->less_flat) << "stamp " << stamp;
    EXPECT_EQ(frame->frame.full.get(), &features->features->full) << "stamp " << stamp;
  }
  EXPECT_EQ(aloam::ros_io::wireConversions(), conversions_before) << "a stage message was serialized";
  spinner.stop();
}

}  // namespace

int main(int argc, char** argv)
{
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_zero_copy");
  return RUN_ALL_TESTS();
}
