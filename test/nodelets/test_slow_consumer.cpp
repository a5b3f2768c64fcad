// A slow consumer inside the manager: the three nodelets loaded into this process's nodelet loader, and
// subscribers in the same process (intra-process: they get the very messages the nodelets publish) whose
// callbacks sleep, on a queue of their own. The pipeline must keep answering every sweep at full rate,
// the slow subscribers must really get messages, and unloading the nodelets while slow callbacks still
// hold their messages must neither deadlock nor leave those messages dangling.
#include <atomic>
#include <cmath>
#include <condition_variable>
#include <mutex>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <nav_msgs/Odometry.h>
#include <nav_msgs/Path.h>
#include <nodelet/loader.h>
#include <ros/callback_queue.h>
#include <ros/ros.h>
#include <sensor_msgs/PointCloud2.h>

#include "aloam_nodelet/ros/conversions.h"
#include "aloam_nodelet/ros/stage_messages.h"
#include "aloam_nodelet/sim/long_drive.h"

namespace
{
using aloam::ros_io::StampedFeatureSet;
using aloam::ros_io::StampedOdometryFrame;

constexpr int kSweeps = 40;
constexpr double kAnswerTimeout = 15.0;  // s per sweep, far beyond its processing time
constexpr double kSlowCallback = 0.3;    // s each slow callback sleeps

// Counts what a slow subscriber received and keeps the last odometry frame it was handed.
struct SlowConsumer
{
  std::atomic<int> received{ 0 };
  StampedOdometryFrame::ConstPtr last_frame;
  std::mutex mutex;

  template <typename M>
  void sleepy(const boost::shared_ptr<const M>&)
  {
    ++received;
    std::this_thread::sleep_for(std::chrono::duration<double>(kSlowCallback));
  }
  void frame(const StampedOdometryFrame::ConstPtr& msg)
  {
    {
      std::lock_guard<std::mutex> lock(mutex);
      last_frame = msg;
    }
    sleepy(msg);
  }
};

// Waits for the full-rate answer of each sweep.
struct Answers
{
  std::mutex mutex;
  std::condition_variable cv;
  ros::Time last;
  bool finite = true;

  void cb(const nav_msgs::Odometry::ConstPtr& msg)
  {
    std::lock_guard<std::mutex> lock(mutex);
    const auto& p = msg->pose.pose.position;
    finite = finite && std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z);
    last = msg->header.stamp;
    cv.notify_all();
  }
  bool waitFor(const ros::Time& stamp)
  {
    std::unique_lock<std::mutex> lock(mutex);
    return cv.wait_for(lock, std::chrono::duration<double>(kAnswerTimeout), [&] { return last >= stamp; });
  }
};

TEST(SlowConsumer, InProcessSleepersNeitherStallNorOutliveThePipeline)
{
  ros::NodeHandle nh;
  auto loader = std::make_unique<nodelet::Loader>(false);
  ASSERT_TRUE(loader->load("/scan_registration", "aloam_nodelet/ScanRegistration", {}, {}));
  ASSERT_TRUE(loader->load("/laser_odometry", "aloam_nodelet/LaserOdometry", {}, {}));
  ASSERT_TRUE(loader->load("/laser_mapping", "aloam_nodelet/LaserMapping", {}, {}));

  // The slow subscribers on a queue (and spinner) of their own, queues of one and of many.
  ros::NodeHandle slow_nh;
  ros::CallbackQueue slow_queue;
  slow_nh.setCallbackQueue(&slow_queue);
  SlowConsumer slow;
  std::vector<ros::Subscriber> slow_subs = {
    slow_nh.subscribe("laser_features", 1, &SlowConsumer::sleepy<StampedFeatureSet>, &slow),
    slow_nh.subscribe("laser_odom_frame", 100, &SlowConsumer::frame, &slow),
    slow_nh.subscribe("aft_mapped_to_init", 1, &SlowConsumer::sleepy<nav_msgs::Odometry>, &slow),
    slow_nh.subscribe("aft_mapped_path", 100, &SlowConsumer::sleepy<nav_msgs::Path>, &slow),
    slow_nh.subscribe("velodyne_cloud_registered", 1, &SlowConsumer::sleepy<sensor_msgs::PointCloud2>, &slow),
  };
  ros::AsyncSpinner slow_spinner(1, &slow_queue);
  slow_spinner.start();

  Answers answers;
  ros::Subscriber answer_sub = nh.subscribe("aft_mapped_to_init_high_frec", 10, &Answers::cb, &answers);
  ros::Publisher points_pub = nh.advertise<sensor_msgs::PointCloud2>("velodyne_points", 1);
  ros::AsyncSpinner spinner(1);
  spinner.start();
  for (int i = 0; i < 100 && points_pub.getNumSubscribers() == 0; ++i)
  {
    ros::Duration(0.1).sleep();
  }
  ASSERT_GT(points_pub.getNumSubscribers(), 0u);

  aloam::sim::LongDrive drive;
  const aloam::SensorModel sensor = *aloam::SensorModel::fromPreset("VLP16");
  for (int k = 0; k < kSweeps; ++k)
  {
    auto msg = boost::make_shared<sensor_msgs::PointCloud2>();
    std_msgs::Header header;
    header.stamp = ros::Time(500.0 + drive.sweepStamp(k));
    header.frame_id = "velodyne";
    aloam::ros_io::toPointCloud2(drive.sweep(k, sensor), header, *msg);
    points_pub.publish(msg);
    ASSERT_TRUE(answers.waitFor(header.stamp)) << "sweep " << k << " not answered with slow consumers attached";
  }
  EXPECT_TRUE(answers.finite);
  EXPECT_GT(slow.received.load(), 0);
  std::printf("%d sweeps answered at full rate; the slow consumers took %d messages (%.1f s each)\n", kSweeps,
              slow.received.load(), kSlowCallback);
  // Let the slow callbacks run while the nodelets go on, then unload in the middle of one.
  ros::Duration(1.0).sleep();

  // Unload every nodelet while slow callbacks are still running or queued.
  const auto unload_start = std::chrono::steady_clock::now();
  loader.reset();
  std::printf("nodelets unloaded in %.2f s with slow consumers attached\n",
              std::chrono::duration<double>(std::chrono::steady_clock::now() - unload_start).count());
  // A message a slow consumer holds stays valid after its publisher is gone (shared ownership).
  StampedOdometryFrame::ConstPtr held;
  {
    std::lock_guard<std::mutex> lock(slow.mutex);
    held = slow.last_frame;
  }
  ASSERT_TRUE(held);
  ASSERT_TRUE(held->frame.full);
  std::size_t finite = 0;
  for (const aloam::Point& p : held->frame.full->points)
  {
    finite += std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z) ? 1 : 0;
  }
  EXPECT_EQ(finite, held->frame.full->size());
  EXPECT_GT(finite, 0u);
  slow_spinner.stop();
  spinner.stop();
}

}  // namespace

int main(int argc, char** argv)
{
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_slow_consumer");
  return RUN_ALL_TESTS();
}
