// Mapping behind: the mapping nodelet loaded into this process's nodelet loader, fed odometry frames (made
// here by the core pipeline from a simulated drive) faster than it registers them. A registration that
// takes longer than ~scan_period makes mapping "behind": frames then wait in its one-frame slot for the
// lane, which registers the newest, and older ones are skipped and counted in the diagnostics.
//
// A tiny ~scan_period (10 ms, the least allowed) and a heavy registration (more iterations, finer map
// leaves) make every registration count as behind. Frames go out in bursts of five back to back, each
// burst once the last one is mapped and added to the map: while the lane (or the callback thread) registers
// the first, the others pile up in the slot. Nothing asserts a duration: the test repeats bursts until a
// skip is reported (one burst does it unless registering takes under a millisecond), then checks what was
// published against what was fed. Timeouts are minutes, for a loaded 2-core machine.
#include <algorithm>
#include <condition_variable>
#include <mutex>
#include <set>
#include <string>
#include <vector>

#include <diagnostic_msgs/DiagnosticArray.h>
#include <gtest/gtest.h>
#include <nav_msgs/Odometry.h>
#include <nodelet/loader.h>
#include <ros/ros.h>
#include <sensor_msgs/PointCloud2.h>

#include "aloam_nodelet/core/pipeline.h"
#include "aloam_nodelet/ros/stage_messages.h"
#include "aloam_nodelet/sim/long_drive.h"

namespace
{
using aloam::ros_io::StampedOdometryFrame;

constexpr double kFirstStamp = 1000.0;  // s; the drive's sweep stamps are added to it
constexpr int kWarmUpFrames = 3;        // fed one at a time: the first registrations have little map
constexpr int kBurst = 5;               // frames back to back; the nodelet's subscription queue holds 5
constexpr int kMaxBursts = 20;
constexpr double kTimeout = 180.0;  // s for any one awaited event

/// Odometry frames of a simulated drive, as the odometry nodelet would publish them.
class FrameSource
{
public:
  FrameSource() : sensor_(*aloam::SensorModel::fromPreset("VLP16")) {}

  StampedOdometryFrame::Ptr next()
  {
    while (true)
    {
      const long k = sweep_++;
      const double stamp = kFirstStamp + drive_.sweepStamp(k);
      const aloam::PipelineOutput out = pipeline_.processOdometry(drive_.sweep(k, sensor_), stamp, true, true);
      if (out.status != aloam::PipelineStatus::kOk)
      {
        continue;  // not a frame odometry would publish
      }
      auto msg = boost::make_shared<StampedOdometryFrame>();
      msg->header.stamp = ros::Time(stamp);
      msg->header.frame_id = "camera_init";
      msg->child_frame_id = "laser_odom";
      msg->sensor_frame_id = "velodyne";
      msg->frame = out.odometry;
      msg->frame.stamp = msg->header.stamp.toSec();
      return msg;
    }
  }

private:
  aloam::sim::LongDrive drive_;
  aloam::SensorModel sensor_;
  aloam::Pipeline pipeline_;
  long sweep_ = 0;
};

/// What the mapping nodelet published, as it came.
class Observed
{
public:
  void mapped(const nav_msgs::Odometry::ConstPtr& msg)
  {
    std::lock_guard<std::mutex> lock(mutex_);
    mapped_.push_back(msg->header.stamp);
    cv_.notify_all();
  }
  // The registered cloud goes out when a frame has been added to the map (the map update).
  void added(const sensor_msgs::PointCloud2::ConstPtr& msg)
  {
    std::lock_guard<std::mutex> lock(mutex_);
    last_added_ = std::max(last_added_, msg->header.stamp);
    cv_.notify_all();
  }
  void diagnostics(const diagnostic_msgs::DiagnosticArray::ConstPtr& msg)
  {
    for (const auto& status : msg->status)
    {
      if (status.name.find("laser_mapping") == std::string::npos)
      {
        continue;
      }
      long skipped = -1, frames = -1;
      for (const auto& kv : status.values)
      {
        if (kv.key == "frames skipped (mapping behind)")
        {
          skipped = std::stol(kv.value);
        }
        else if (kv.key == "frames")
        {
          frames = std::stol(kv.value);
        }
        else if (kv.key == "mean frame (ms)")
        {
          std::lock_guard<std::mutex> lock(mutex_);
          mean_ms_ = kv.value;
        }
      }
      if (skipped >= 0 && frames >= 0)
      {
        std::lock_guard<std::mutex> lock(mutex_);
        skipped_ = skipped;
        frames_ = frames;
        cv_.notify_all();
      }
    }
  }

  /// Waits until `stamp` has been mapped and added to the map.
  bool waitMappedAndAdded(const ros::Time& stamp)
  {
    std::unique_lock<std::mutex> lock(mutex_);
    return cv_.wait_for(lock, std::chrono::duration<double>(kTimeout),
                        [&] { return !mapped_.empty() && mapped_.back() >= stamp && last_added_ >= stamp; });
  }
  /// Waits for diagnostics that count `frames` registrations; returns the skipped count they report.
  long skippedOnceCounted(std::size_t frames)
  {
    std::unique_lock<std::mutex> lock(mutex_);
    cv_.wait_for(lock, std::chrono::duration<double>(kTimeout), [&] { return frames_ >= static_cast<long>(frames); });
    return frames_ == static_cast<long>(frames) ? skipped_ : -1;
  }
  long skipped()
  {
    std::lock_guard<std::mutex> lock(mutex_);
    return skipped_;
  }
  std::vector<ros::Time> mappedStamps()
  {
    std::lock_guard<std::mutex> lock(mutex_);
    return mapped_;
  }
  std::string meanMs()
  {
    std::lock_guard<std::mutex> lock(mutex_);
    return mean_ms_;
  }

private:
  std::mutex mutex_;
  std::condition_variable cv_;
  std::vector<ros::Time> mapped_;
  ros::Time last_added_;
  long skipped_ = -1, frames_ = -1;
  std::string mean_ms_ = "?";
};

TEST(MappingBehind, TheNewestWaitingFrameIsMappedAndOlderOnesAreSkipped)
{
  ros::NodeHandle nh;
  // Every registration counts as behind: ~scan_period at its least, and more work per registration.
  ros::param::set("/laser_mapping/scan_period", 0.01);
  ros::param::set("/laser_mapping/max_gap_sweeps", 1000.0);  // 0.1 s steps are no gap
  ros::param::set("/laser_mapping/outer_iterations", 6);
  ros::param::set("/laser_mapping/max_iterations", 20);
  ros::param::set("/laser_mapping/plane_neighbours", 10);
  ros::param::set("/laser_mapping/corner_leaf_size", 0.1);
  ros::param::set("/laser_mapping/surf_leaf_size", 0.1);
  nodelet::Loader loader(false);
  ASSERT_TRUE(loader.load("/laser_mapping", "aloam_nodelet/LaserMapping", {}, {}));

  Observed observed;
  ros::Subscriber mapped_sub = nh.subscribe("aft_mapped_to_init", 1000, &Observed::mapped, &observed);
  ros::Subscriber added_sub = nh.subscribe("velodyne_cloud_registered", 100, &Observed::added, &observed);
  ros::Subscriber diag_sub = nh.subscribe("/diagnostics", 100, &Observed::diagnostics, &observed);
  ros::Publisher frame_pub = nh.advertise<StampedOdometryFrame>("laser_odom_frame", kBurst);
  ros::AsyncSpinner spinner(1);
  spinner.start();
  for (int i = 0; i < 100 && frame_pub.getNumSubscribers() == 0; ++i)
  {
    ros::Duration(0.1).sleep();
  }
  ASSERT_GT(frame_pub.getNumSubscribers(), 0u);

  FrameSource source;
  std::vector<ros::Time> fed;
  auto feed = [&](const std::vector<StampedOdometryFrame::Ptr>& frames)
  {
    for (const auto& frame : frames)
    {
      fed.push_back(frame->header.stamp);
      frame_pub.publish(frame);  // in-process: the nodelet gets this very object
    }
  };
  for (int i = 0; i < kWarmUpFrames; ++i)
  {
    feed({ source.next() });
    ASSERT_TRUE(observed.waitMappedAndAdded(fed.back())) << "warm-up frame " << i << " not mapped";
  }
  int bursts = 0;
  while (bursts < kMaxBursts && observed.skipped() <= 0)
  {
    std::vector<StampedOdometryFrame::Ptr> burst;
    for (int i = 0; i < kBurst; ++i)
    {
      burst.push_back(source.next());  // made before any goes out, so they go out back to back
    }
    feed(burst);
    ++bursts;
    // The newest frame of the burst must come through, whatever was skipped before it.
    ASSERT_TRUE(observed.waitMappedAndAdded(fed.back()))
        << "burst " << bursts << ": its last frame " << fed.back() << " was not mapped";
  }

  const std::vector<ros::Time> mapped = observed.mappedStamps();
  const long skipped = observed.skippedOnceCounted(mapped.size());
  std::printf("%zu frames fed (%d bursts of %d), %zu mapped, %ld skipped; mean registration %s ms\n", fed.size(),
              bursts, kBurst, mapped.size(), skipped, observed.meanMs().c_str());
  ASSERT_FALSE(mapped.empty());
  EXPECT_EQ(mapped.back(), fed.back()) << "the last frame fed is the last one mapped";
  const std::set<ros::Time> fed_set(fed.begin(), fed.end());
  for (std::size_t i = 0; i < mapped.size(); ++i)
  {
    EXPECT_TRUE(fed_set.count(mapped[i]) == 1) << "mapped pose " << i << " at " << mapped[i] << " was never fed";
    if (i > 0)
    {
      EXPECT_LT(mapped[i - 1], mapped[i]) << "mapped poses " << i - 1 << " and " << i << " out of order";
    }
  }
  EXPECT_GT(skipped, 0) << "no frame skipped in " << bursts << " bursts (diagnostics: -1 = never counted all "
                        << mapped.size() << " registrations)";
  // Every frame is either registered or skipped (no ROS queue drops: a burst fits the subscription queue).
  EXPECT_EQ(static_cast<std::size_t>(skipped) + mapped.size(), fed.size());
  spinner.stop();
}

}  // namespace

int main(int argc, char** argv)
{
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_mapping_behind");
  return RUN_ALL_TESTS();
}
