// Feeds the running pipeline a long simulated drive (sim::LongDrive, VLP-16) on velodyne_points, sweep by
// sweep: each is published when the previous one was answered on aft_mapped_to_init_high_frec, so the run is
// as fast as the pipeline and no sweep is lost in a queue. For the nodelet memory rostest.
// Usage: long_drive_publisher SWEEPS [SEED]   (ROS node; exit 0 when every sweep was answered)
#include <condition_variable>
#include <cstdio>
#include <mutex>
#include <string>

#include <nav_msgs/Odometry.h>
#include <pcl_conversions/pcl_conversions.h>
#include <ros/ros.h>
#include <sensor_msgs/PointCloud2.h>

#include "aloam_nodelet/sim/long_drive.h"

namespace
{
constexpr double kAnswerTimeout = 15.0;  // s; far beyond a sweep's processing time
constexpr double kStartStamp = 2000.0;   // s, stamp of the first sweep's start

std::mutex mutex;
std::condition_variable answered_cv;
ros::Time last_answer;

void answerCb(const nav_msgs::Odometry::ConstPtr& msg)
{
  std::lock_guard<std::mutex> lock(mutex);
  last_answer = msg->header.stamp;
  answered_cv.notify_all();
}
}  // namespace

int main(int argc, char** argv)
{
  ros::init(argc, argv, "long_drive_publisher");
  if (argc < 2)
  {
    std::fprintf(stderr, "usage: long_drive_publisher SWEEPS [SEED]\n");
    return 2;
  }
  const long sweeps = std::stol(argv[1]);
  aloam::sim::LongDriveOptions options;
  options.seed = argc > 2 ? static_cast<unsigned>(std::stoul(argv[2])) : 1u;
  aloam::sim::LongDrive drive(options);
  const aloam::SensorModel sensor = *aloam::SensorModel::fromPreset("VLP16");

  ros::NodeHandle nh;
  ros::Publisher pub = nh.advertise<sensor_msgs::PointCloud2>("velodyne_points", 1);
  ros::Subscriber sub = nh.subscribe("aft_mapped_to_init_high_frec", 10, answerCb);
  ros::AsyncSpinner spinner(1);
  spinner.start();
  const ros::WallTime wait_until = ros::WallTime::now() + ros::WallDuration(30.0);
  while ((pub.getNumSubscribers() == 0 || sub.getNumPublishers() == 0) && ros::WallTime::now() < wait_until)
  {
    ros::WallDuration(0.1).sleep();
  }

  long unanswered = 0;
  for (long k = 0; k < sweeps && ros::ok(); ++k)
  {
    auto msg = boost::make_shared<sensor_msgs::PointCloud2>();
    pcl::toROSMsg(drive.sweep(k, sensor), *msg);
    msg->header.frame_id = "velodyne";
    msg->header.stamp = ros::Time(kStartStamp + drive.sweepStamp(k));
    const ros::Time stamp = msg->header.stamp;
    pub.publish(msg);
    std::unique_lock<std::mutex> lock(mutex);
    if (!answered_cv.wait_for(lock, std::chrono::duration<double>(kAnswerTimeout),
                              [&] { return last_answer >= stamp; }))
    {
      ++unanswered;
      std::printf("sweep %ld not answered within %.0f s\n", k, kAnswerTimeout);
    }
    if ((k + 1) % 100 == 0)
    {
      std::printf("long_drive_publisher: %ld sweeps (%.0f m)\n", k + 1,
                  drive.sweepEndPose(k).translation().x() - drive.sweepEndPose(0).translation().x());
      std::fflush(stdout);
    }
  }
  std::printf("long_drive_publisher: %ld sweeps, %ld unanswered\n", sweeps, unanswered);
  return unanswered == 0 ? 0 : 1;
}
