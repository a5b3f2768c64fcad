// Writes a rosbag of simulated sweeps (sensor_msgs/PointCloud2 on velodyne_points, Velodyne field
// layout with ring and time) driving along the synthetic street, and the exact ground truth as KITTI
// pose rows (sensor pose at each sweep's end, relative to the first). For the end-to-end --bag check.
// Usage: make_test_bag OUT.bag OUT_GT.txt [SENSOR] [SWEEPS]
#include <cmath>
#include <iostream>
#include <string>

#include <pcl_conversions/pcl_conversions.h>
#include <rosbag/bag.h>
#include <sensor_msgs/PointCloud2.h>

#include "aloam_nodelet/eval/trajectory_io.h"
#include "aloam_nodelet/sim/raycaster.h"
#include "aloam_nodelet/sim/scene.h"

namespace
{
constexpr double kSpeed = 10.0;         // m/s along the street
constexpr double kSensorHeight = 1.8;   // m
constexpr double kSwayAmplitude = 0.8;  // m, lateral weave
constexpr double kSwayRate = 0.4;       // rad/s
constexpr double kStartStamp = 1000.0;  // s, stamp of the first sweep
constexpr unsigned kSceneSeed = 7;

// World <- sensor at time t: forward at constant speed, weaving gently, heading along the motion.
Eigen::Isometry3d poseAt(double t)
{
  const double x = 10.0 + kSpeed * t;
  const double y = kSwayAmplitude * std::sin(kSwayRate * t);
  const double heading = std::atan2(kSwayAmplitude * kSwayRate * std::cos(kSwayRate * t), kSpeed);
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translation() = Eigen::Vector3d(x, y, kSensorHeight);
  pose.linear() = Eigen::AngleAxisd(heading, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return pose;
}
}  // namespace

int main(int argc, char** argv)
{
  if (argc < 3)
  {
    std::cerr << "usage: make_test_bag OUT.bag OUT_GT.txt [SENSOR] [SWEEPS]\n";
    return 2;
  }
  const std::string sensor_name = argc > 3 ? argv[3] : "VLP16";
  const int sweeps = argc > 4 ? std::stoi(argv[4]) : 40;
  const auto sensor = aloam::SensorModel::fromPreset(sensor_name);
  if (!sensor || sweeps < 2)
  {
    std::cerr << "make_test_bag: unknown sensor or too few sweeps\n";
    return 2;
  }
  const double period = sensor->scanPeriod();
  const auto scene = aloam::sim::Scene::urbanStreet(kSceneSeed, kSpeed * period * sweeps + 150.0);

  rosbag::Bag bag(argv[1], rosbag::bagmode::Write);
  aloam::eval::Trajectory truth;
  const Eigen::Isometry3d first_end = poseAt(period);
  for (int k = 0; k < sweeps; ++k)
  {
    const double start = k * period;
    aloam::sim::ScanOptions options;
    options.range_noise_sigma = 0.01;
    options.seed = static_cast<unsigned>(k);
    const aloam::Cloud cloud = aloam::sim::scan(
        scene, *sensor, [&](double t) { return poseAt(start + t); }, options);
    sensor_msgs::PointCloud2 msg;
    pcl::toROSMsg(cloud, msg);
    msg.header.frame_id = "velodyne";
    msg.header.stamp = ros::Time(kStartStamp + start);
    msg.header.seq = static_cast<std::uint32_t>(k);
    bag.write("velodyne_points", msg.header.stamp, msg);
    truth.push_back(first_end.inverse() * poseAt(start + period));
  }
  bag.close();
  aloam::eval::writeKittiPoses(argv[2], truth);
  std::cout << "wrote " << sweeps << " " << sensor_name << " sweeps to " << argv[1] << "\n";
  return 0;
}
