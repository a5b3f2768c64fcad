// No thread outlives its nodelet (README "Threads"): the three stages loaded into this process's nodelet
// loader, a few sweeps played through them, then unloaded; the process's threads (/proc/self/task) must come
// back to what they were before the load. Twice: once with the stages idle at the unload, once unloading
// with sweeps still in flight (lanes and callbacks busy). Mapping runs with tf_mode rep105, so its TF
// listener's thread is counted too. Thread exits are polled for (minutes at most), nothing waits for a
// fixed time.
#include <chrono>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nav_msgs/Odometry.h>
#include <nodelet/loader.h>
#include <ros/ros.h>
#include <sensor_msgs/PointCloud2.h>

#include "../core/thread_support.h"
#include "aloam_nodelet/ros/conversions.h"
#include "aloam_nodelet/sim/long_drive.h"

namespace
{
constexpr int kSweeps = 8;
constexpr double kTimeout = 120.0;  // s for one sweep to be mapped, or for threads to end

using aloam_test::settledThreadCount;
using aloam_test::threadsDropTo;
using aloam_test::threadsOfThisProcess;

struct Mapped
{
  std::mutex mutex;
  std::condition_variable cv;
  ros::Time last;
  std::size_t count = 0;

  void cb(const nav_msgs::Odometry::ConstPtr& msg)
  {
    std::lock_guard<std::mutex> lock(mutex);
    last = std::max(last, msg->header.stamp);
    ++count;
    cv.notify_all();
  }
  bool waitFor(const ros::Time& stamp)
  {
    std::unique_lock<std::mutex> lock(mutex);
    return cv.wait_for(lock, std::chrono::duration<double>(kTimeout), [&] { return last >= stamp; });
  }
  std::size_t received()
  {
    std::lock_guard<std::mutex> lock(mutex);
    return count;
  }
  bool waitForCount(std::size_t n)
  {
    std::unique_lock<std::mutex> lock(mutex);
    return cv.wait_for(lock, std::chrono::duration<double>(kTimeout), [&] { return count >= n; });
  }
};

TEST(UnloadThreads, NoThreadOutlivesTheNodelets)
{
  ros::NodeHandle nh;
  // roscpp starts one timer thread per clock kind on first use and keeps it for the process: start them
  // here, before counting, since the stages' diagnostics use timers.
  ros::Timer timer = nh.createTimer(ros::Duration(3600.0), [](const ros::TimerEvent&) {});
  ros::WallTimer wall_timer = nh.createWallTimer(ros::WallDuration(3600.0), [](const ros::WallTimerEvent&) {});
  ros::SteadyTimer steady_timer = nh.createSteadyTimer(ros::WallDuration(3600.0), [](const ros::SteadyTimerEvent&) {});
  Mapped mapped;
  ros::Subscriber mapped_sub = nh.subscribe("aft_mapped_to_init", 100, &Mapped::cb, &mapped);
  ros::Publisher points_pub = nh.advertise<sensor_msgs::PointCloud2>("velodyne_points", kSweeps);
  ros::AsyncSpinner spinner(1);
  spinner.start();
  const std::size_t before_loader = settledThreadCount();

  auto loader = std::make_unique<nodelet::Loader>(false);
  const std::size_t with_loader = settledThreadCount();  // its callback threads, no nodelet yet
  ros::param::set("/laser_mapping/tf_mode", "rep105");
  aloam::sim::LongDrive drive;
  const aloam::SensorModel sensor = *aloam::SensorModel::fromPreset("VLP16");
  long sweep = 0;
  for (const bool in_flight : { false, true })
  {
    SCOPED_TRACE(in_flight ? "unloaded with sweeps in flight" : "unloaded idle");
    ASSERT_TRUE(loader->load("/scan_registration", "aloam_nodelet/ScanRegistration", {}, {}));
    ASSERT_TRUE(loader->load("/laser_odometry", "aloam_nodelet/LaserOdometry", {}, {}));
    ASSERT_TRUE(loader->load("/laser_mapping", "aloam_nodelet/LaserMapping", {}, {}));
    for (int i = 0; i < 100 && points_pub.getNumSubscribers() == 0; ++i)
    {
      ros::Duration(0.1).sleep();
    }
    ASSERT_GT(points_pub.getNumSubscribers(), 0u);

    // Made before any goes out, so that in flight they go out back to back.
    std::vector<sensor_msgs::PointCloud2::Ptr> sweeps;
    for (int i = 0; i < kSweeps; ++i, ++sweep)
    {
      auto msg = boost::make_shared<sensor_msgs::PointCloud2>();
      std_msgs::Header header;
      header.stamp = ros::Time(700.0 + drive.sweepStamp(sweep));
      header.frame_id = "velodyne";
      aloam::ros_io::toPointCloud2(drive.sweep(sweep, sensor), header, *msg);
      sweeps.push_back(msg);
    }
    const std::size_t mapped_before = mapped.received();
    for (const auto& msg : sweeps)
    {
      points_pub.publish(msg);
      if (!in_flight)
      {
        ASSERT_TRUE(mapped.waitFor(msg->header.stamp)) << "sweep at " << msg->header.stamp << " not mapped";
      }
    }
    // In flight: unload once one sweep came through (the others may be queued, or dropped by a full queue).
    ASSERT_TRUE(mapped.waitForCount(mapped_before + 1)) << "no sweep mapped";
    // The stages' executors (helpers and lanes) and mapping's TF listener.
    const std::size_t loaded = threadsOfThisProcess();
    EXPECT_GT(loaded, with_loader) << "the loaded stages run no thread of their own: nothing to check";
    std::printf("%s: threads %zu before the loader, %zu with it, %zu with the three stages loaded\n",
                in_flight ? "in flight" : "idle", before_loader, with_loader, loaded);

    for (const char* name : { "/laser_mapping", "/laser_odometry", "/scan_registration" })
    {
      EXPECT_TRUE(loader->unload(name)) << name;
    }
    EXPECT_TRUE(threadsDropTo(with_loader, kTimeout))
        << threadsOfThisProcess() << " threads after unloading, " << with_loader << " before loading";
  }
  loader.reset();
  EXPECT_TRUE(threadsDropTo(before_loader, kTimeout))
      << threadsOfThisProcess() << " threads without the loader, " << before_loader << " before it";
  spinner.stop();
}

}  // namespace

int main(int argc, char** argv)
{
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_unload_threads");
  return RUN_ALL_TESTS();
}
