// Scan registration nodelet: PointCloud2 in (read in place), one FeatureSet out as a shared pointer.
#include <memory>
#include <mutex>

#include <dynamic_reconfigure/server.h>
#include <nodelet/nodelet.h>
#include <pluginlib/class_list_macros.hpp>
#include <ros/ros.h>
#include <sensor_msgs/PointCloud2.h>

#include <aloam_nodelet/ScanRegistrationConfig.h>

#include "aloam_nodelet/core/scan_registration.h"
#include "aloam_nodelet/ros/conversions.h"
#include "aloam_nodelet/ros/pointcloud2_reader.h"
#include "aloam_nodelet/ros/stage_messages.h"
#include "nodelet_common.h"
#include "param_utils.h"
#include "publish_utils.h"
#include "stage_monitor.h"

namespace aloam_nodelet
{
class ScanRegistrationNodelet : public nodelet::Nodelet
{
public:
  ~ScanRegistrationNodelet() override;

private:
  void onInit() override;
  void pointsCb(const sensor_msgs::PointCloud2::ConstPtr& msg);
  bool process(const sensor_msgs::PointCloud2::ConstPtr& msg);  // false: sweep skipped
  void reconfigureCb(ScanRegistrationConfig& config, std::uint32_t level);
  aloam::SensorModel sensorModel(const std::string& preset, int beams) const;

  std::mutex mutex_;                           // guards the core and its configuration
  std::shared_ptr<aloam::Executor> executor_;  // this nodelet's threads, joined on unload
  std::unique_ptr<aloam::ScanRegistration> registration_;
  aloam::ros_io::ReaderOptions reader_options_;
  aloam::Cloud input_;                                           // reused between sweeps
  double min_elevation_deg_ = -15.0, max_elevation_deg_ = 15.0;  // for a beam count instead of a preset
  StampGuard stamps_;  // drops duplicate and late sweeps before any work is done on them
  aloam::RegistrationStats last_stats_;
  std::size_t last_features_[4] = { 0, 0, 0, 0 };  // sharp, less sharp, flat, less flat
  StageMonitor monitor_;

  std::unique_ptr<dynamic_reconfigure::Server<ScanRegistrationConfig>> reconfigure_server_;

  ros::Subscriber points_sub_;
  ros::Publisher features_pub_;
  ros::Publisher sharp_pub_, less_sharp_pub_, flat_pub_, less_flat_pub_, full_pub_;
};

ScanRegistrationNodelet::~ScanRegistrationNodelet()
{
  // A sweep's callback may still be running on the manager's threads during an unload, and the publishers
  // it uses are declared after the subscriber (destroyed first): shutting the subscriber down waits for it.
  points_sub_.shutdown();
}

aloam::SensorModel ScanRegistrationNodelet::sensorModel(const std::string& preset, int beams) const
{
  if (beams > 0)
  {
    NODELET_INFO("sensor: %d beams from %.2f to %.2f deg", beams, min_elevation_deg_, max_elevation_deg_);
    return aloam::SensorModel::uniform(beams, min_elevation_deg_, max_elevation_deg_);
  }
  if (const auto model = aloam::SensorModel::fromPreset(preset))
  {
    NODELET_INFO("sensor: %s", preset.c_str());
    return *model;
  }
  NODELET_ERROR("unknown sensor preset '%s' (VLP16, HDL32, HDL64, VLP32C, OS1_64, OS0_64, OS1_128); using VLP16",
                preset.c_str());
  return *aloam::SensorModel::fromPreset("VLP16");
}

void ScanRegistrationNodelet::onInit()
{
  ros::NodeHandle& nh = getNodeHandle();
  ros::NodeHandle& pnh = getPrivateNodeHandle();
  const std::string& name = getName();

  // Read once at start-up; the rest comes through dynamic_reconfigure (reconfigureCb).
  aloam::ScanRegistrationConfig config;
  config.scan_period = boundedParam(pnh, name, "scan_period", config.scan_period, 0.01, 1.0);
  config.threads = boundedParam(pnh, name, "threads", config.threads, 1, 16);
  pnh.param("min_elevation_deg", min_elevation_deg_, min_elevation_deg_);
  pnh.param("max_elevation_deg", max_elevation_deg_, max_elevation_deg_);
  reader_options_.scan_period = config.scan_period;
  reader_options_.max_points = static_cast<std::size_t>(
      boundedParam(pnh, name, "max_points", static_cast<int>(reader_options_.max_points), 1000, 20'000'000));
  executor_ = std::make_shared<aloam::Executor>(config.threads);
  reader_options_.executor = executor_.get();  // large sweeps are read on the stage's threads
  registration_ = std::make_unique<aloam::ScanRegistration>(config, executor_);
  stamps_.setConfig(stampCheckParams(pnh, name));

  warnOutOfRange<ScanRegistrationConfig>(pnh, name);
  reconfigure_server_ = std::make_unique<dynamic_reconfigure::Server<ScanRegistrationConfig>>(pnh);
  reconfigure_server_->setCallback([this](ScanRegistrationConfig& c, std::uint32_t level) { reconfigureCb(c, level); });

  features_pub_ = nh.advertise<aloam::ros_io::StampedFeatureSet>("laser_features", 2);
  sharp_pub_ = nh.advertise<sensor_msgs::PointCloud2>("laser_cloud_sharp", 2);
  less_sharp_pub_ = nh.advertise<sensor_msgs::PointCloud2>("laser_cloud_less_sharp", 2);
  flat_pub_ = nh.advertise<sensor_msgs::PointCloud2>("laser_cloud_flat", 2);
  less_flat_pub_ = nh.advertise<sensor_msgs::PointCloud2>("laser_cloud_less_flat", 2);
  full_pub_ = nh.advertise<sensor_msgs::PointCloud2>("velodyne_cloud_2", 2);
  monitor_.init(nh, pnh, name,
                [this](diagnostic_updater::DiagnosticStatusWrapper& s)
                {
                  std::lock_guard<std::mutex> lock(mutex_);
                  s.add("points in", last_stats_.points_in);
                  s.add("points used", last_stats_.points_used);
                  s.add("points on no ring", last_stats_.unassigned_ring);
                  s.add("points NaN/Inf", last_stats_.invalid);
                  s.add("points out of range", last_stats_.out_of_range);
                  s.add("rings", last_stats_.rings);
                  s.addf("features (sharp, less sharp, flat, less flat)", "%zu, %zu, %zu, %zu", last_features_[0],
                         last_features_[1], last_features_[2], last_features_[3]);
                  stamps_.report(s);
                });
  // Queue of one: always the newest sweep.
  points_sub_ = nh.subscribe("velodyne_points", 1, &ScanRegistrationNodelet::pointsCb, this);
}

void ScanRegistrationNodelet::reconfigureCb(ScanRegistrationConfig& c, std::uint32_t level)
{
  constexpr std::uint32_t kReinitialise = 1;  // level of the ring model in ScanRegistration.cfg
  std::lock_guard<std::mutex> lock(mutex_);
  aloam::ScanRegistrationConfig config = registration_->config();
  if (level & kReinitialise)
  {
    config.sensor = sensorModel(c.sensor, c.beams);
  }
  if (c.maximum_range <= c.minimum_range)
  {
    NODELET_WARN("maximum_range %.2f <= minimum_range %.2f; using minimum_range + 1 m", c.maximum_range,
                 c.minimum_range);
    c.maximum_range = c.minimum_range + 1.0;
  }
  config.minimum_range = c.minimum_range;
  config.maximum_range = c.maximum_range;
  config.less_flat_leaf_size = c.less_flat_leaf_size;
  config.curvature_threshold = c.curvature_threshold;
  config.reject_occluded = c.reject_occluded;
  config.occlusion_continuity = c.occlusion_continuity;
  config.occlusion_straight_tolerance = c.occlusion_straight_tolerance;
  config.curvature_across_ring = c.curvature_across_ring;
  registration_->setConfig(config);  // applies from the next sweep
}

void ScanRegistrationNodelet::pointsCb(const sensor_msgs::PointCloud2::ConstPtr& msg)
{
  const auto start = std::chrono::steady_clock::now();
  if (process(msg))
  {
    monitor_.frameDone(msSince(start));
  }
}

bool ScanRegistrationNodelet::process(const sensor_msgs::PointCloud2::ConstPtr& msg)
{
  std::lock_guard<std::mutex> lock(mutex_);
  // Gaps and jumps back pass (aloam::actionFor): odometry and mapping, which keep state over time, act on them.
  const aloam::StampVerdict verdict = stamps_.check(msg->header.stamp);
  if (!aloam::actionFor(verdict).process)
  {
    if (stamps_.warningDue(verdict))
    {
      NODELET_WARN_STREAM(stamps_.dropMessage(verdict, "velodyne_points", msg->header.stamp));
    }
    return false;
  }
  const aloam::ros_io::ReadReport report = aloam::ros_io::readPointCloud2(*msg, reader_options_, input_);
  for (const std::string& warning : report.warnings)
  {
    NODELET_WARN_STREAM_THROTTLE(kThrottleSeconds, "velodyne_points: " << warning);
  }
  if (!report.ok)
  {
    NODELET_WARN_STREAM_THROTTLE(kThrottleSeconds, "velodyne_points: sweep skipped: " << report.error);
    return false;
  }

  auto features = std::make_shared<aloam::FeatureSet>();
  if (!registration_->process(input_, msg->header.stamp.toSec(), report.has_ring, report.has_time, *features))
  {
    NODELET_WARN_THROTTLE(kThrottleSeconds, "velodyne_points: sweep skipped: %zu of %zu points usable",
                          features->stats.points_used, features->stats.points_in);
    last_stats_ = features->stats;
    return false;
  }
  last_stats_ = features->stats;
  last_features_[0] = features->sharp.size();
  last_features_[1] = features->less_sharp.size();
  last_features_[2] = features->flat.size();
  last_features_[3] = features->less_flat.size();
  if (features->stats.unassigned_ring > 0)
  {
    NODELET_DEBUG("%zu points fit no beam of the sensor model", features->stats.unassigned_ring);
  }

  auto out = boost::make_shared<aloam::ros_io::StampedFeatureSet>();
  out->header = msg->header;
  out->features = features;
  features_pub_.publish(out);  // never modified after this

  publishCloudIfSubscribed(sharp_pub_, features->sharp, msg->header);
  publishCloudIfSubscribed(less_sharp_pub_, features->less_sharp, msg->header);
  publishCloudIfSubscribed(flat_pub_, features->flat, msg->header);
  publishCloudIfSubscribed(less_flat_pub_, features->less_flat, msg->header);
  publishCloudIfSubscribed(full_pub_, features->full, msg->header);
  return true;
}

}  // namespace aloam_nodelet

PLUGINLIB_EXPORT_CLASS(aloam_nodelet::ScanRegistrationNodelet, nodelet::Nodelet)
