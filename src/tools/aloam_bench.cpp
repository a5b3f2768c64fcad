// aloam_bench: speed and memory of the LOAM core on real and simulated sweeps (offline), and the
// latency of a running nodelet pipeline fed at the sensor rate (--live).
#include <sys/resource.h>
#include <time.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <map>
#include <memory>
#include <mutex>
#include <numeric>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <nav_msgs/Odometry.h>
#include <ros/ros.h>
#include <sensor_msgs/PointCloud2.h>

#include "aloam_nodelet/core/pipeline.h"
#include "aloam_nodelet/eval/kitti_metrics.h"
#include "aloam_nodelet/eval/timing_stats.h"
#include "aloam_nodelet/eval/trajectory_io.h"
#include "aloam_nodelet/io/kitti_dataset.h"
#include "aloam_nodelet/sim/long_drive.h"
#include "aloam_nodelet/sim/raycaster.h"
#include "aloam_nodelet/sim/scenes_extra.h"
#include "aloam_nodelet/sim/trajectories.h"

namespace fs = std::filesystem;
using aloam::eval::formatMs;
using aloam::eval::summarize;

namespace
{
constexpr double kSweepPeriod = 0.1;
constexpr unsigned kSimSeed = 7;

const char* const kUsage =
    "usage: aloam_bench [--kitti DIR] [--sim-sweeps N] [--long-sweeps N] [--only kitti|sim|long] [--pace HZ]\n"
    "                   [--threads N]\n"
    "       aloam_bench --live [--kitti DIR] [--rate HZ] [--topic TOPIC] [--answer TOPIC]\n"
    "Offline (default): runs the core stage by stage on KITTI (DIR, default ../shared/data/kitti00_101\n"
    "beside the sources), on simulated urban drives of 16, 32, 64 and 128 beams (N sweeps each, default\n"
    "100) and on a long VLP-16 drive (default 3000 sweeps), and prints per-stage ms (mean, median, p90;\n"
    "wall clock and thread CPU), points per second, peak RSS and the map size over time. --pace HZ feeds\n"
    "the sweeps at that rate instead of back to back (idle gaps as on a robot).\n"
    "--live: publishes the KITTI sweeps at HZ (default 10) on TOPIC (default velodyne_points) into a\n"
    "running pipeline (e.g. roslaunch aloam_nodelet aloam.launch sensor:=HDL64 rviz:=false) and reports\n"
    "the latency from publishing to the mapped pose on ANSWER (default aft_mapped_to_init): median, p90,\n"
    "max, and the sweeps never answered. scripts/bench.sh runs both.\n";

struct Options
{
  std::string kitti = std::string(ALOAM_SOURCE_DIR) + "/../shared/data/kitti00_101";
  int sim_sweeps = 100;
  int long_sweeps = 3000;
  std::string only;
  double pace_hz = 0.0;  // > 0: feed the offline workloads at this rate (idle gaps as on a robot)
  int threads = 2;       // per stage (the nodelets' 'threads')
  bool live = false;
  double rate = 10.0;
  std::string topic = "velodyne_points";
  std::string answer = "aft_mapped_to_init";
};

/// One input sweep, ready for the pipeline.
struct Sweep
{
  aloam::Cloud cloud;
  double stamp = 0.0;
};

/// A workload: sweeps, how to read them, and the ground truth (lidar poses relative to the first sweep
/// end) when there is one. Sweeps come from `sweeps` or, when `generate` is set, are made one at a time
/// outside the timed steps (long drives: memory then shows the pipeline's, not the input's).
struct Workload
{
  std::string name;
  aloam::PipelineConfig config;
  bool has_ring = false;
  bool has_time = false;
  std::vector<Sweep> sweeps;
  std::size_t generated_count = 0;
  std::function<void(std::size_t, Sweep&)> generate;
  aloam::eval::Trajectory truth;
  aloam::eval::EvalOptions eval;

  std::size_t size() const { return generate ? generated_count : sweeps.size(); }
};

double nowMs()
{
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

double threadCpuMs()
{
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return 1e3 * static_cast<double>(ts.tv_sec) + 1e-6 * static_cast<double>(ts.tv_nsec);
}

/// Resident set size now and at its peak (MB), from /proc/self/status.
std::pair<double, double> residentMb()
{
  std::ifstream status("/proc/self/status");
  std::string line;
  double rss = 0.0, peak = 0.0;
  while (std::getline(status, line))
  {
    std::istringstream fields(line);
    std::string key;
    double kb = 0.0;
    fields >> key >> kb;
    if (key == "VmRSS:")
    {
      rss = kb / 1024.0;
    }
    else if (key == "VmHWM:")
    {
      peak = kb / 1024.0;
    }
  }
  return { rss, peak };
}

/// Wall and CPU milliseconds of one step.
class StepTimer
{
public:
  StepTimer() : wall_(nowMs()), cpu_(threadCpuMs()) {}
  void stop(std::vector<double>& wall, std::vector<double>& cpu) const
  {
    wall.push_back(nowMs() - wall_);
    cpu.push_back(threadCpuMs() - cpu_);
  }

private:
  double wall_;
  double cpu_;
};

struct StageSeries
{
  std::vector<double> wall, cpu;
};

void printStage(const char* name, const StageSeries& s)
{
  std::printf("  %-14s %s   cpu mean %6.1f ms\n", name, formatMs(summarize(s.wall)).c_str(), summarize(s.cpu).mean);
}

/// Runs the core on a workload stage by stage (the nodelets' split: the map update comes after the pose)
/// and prints the figures.
void runWorkload(const Workload& w, double pace_hz, int threads)
{
  aloam::PipelineConfig config = w.config;
  config.registration.threads = config.odometry.threads = config.mapping.threads = threads;
  std::printf("\n== %s: %zu sweeps (RSS %.1f MB before, %s)\n", w.name.c_str(), w.size(), residentMb().first,
              w.generate ? "sweeps made one at a time, untimed" : "sweeps loaded");
  aloam::ScanRegistration registration(config.registration);
  aloam::LaserOdometry odometry(config.odometry);
  aloam::LaserMapping mapping(config.mapping);
  StageSeries reg, odo, map, update, to_pose;
  aloam::eval::Trajectory estimate;
  std::size_t points = 0, rejected = 0;
  const std::size_t checkpoints = 10;
  const std::size_t every = std::max<std::size_t>(1, w.size() / checkpoints);
  std::vector<std::string> growth;
  std::size_t block_start = 0;
  const double start = nowMs();
  double generating_ms = 0.0;
  Sweep generated;
  for (std::size_t i = 0; i < w.size(); ++i)
  {
    if (w.generate)
    {
      const double t0 = nowMs();
      w.generate(i, generated);
      generating_ms += nowMs() - t0;
    }
    const Sweep& sweep = w.generate ? generated : w.sweeps[i];
    if (pace_hz > 0.0)
    {
      // Wait for the sweep's slot: caches and cores go cold between sweeps, as they do on a robot.
      const double slot = start + 1e3 * double(i) / pace_hz + generating_ms;
      while (nowMs() < slot)
      {
        std::this_thread::sleep_for(std::chrono::microseconds(200));
      }
    }
    points += sweep.cloud.size();
    const double pose_start_wall = nowMs(), pose_start_cpu = threadCpuMs();
    auto features = std::make_shared<aloam::FeatureSet>();
    StepTimer t;
    const bool usable = registration.process(sweep.cloud, sweep.stamp, w.has_ring, w.has_time, *features);
    t.stop(reg.wall, reg.cpu);
    if (!usable)
    {
      ++rejected;
      estimate.push_back(estimate.empty() ? Eigen::Isometry3d::Identity() : estimate.back());
      continue;
    }
    t = StepTimer();
    const aloam::OdometryFrame frame = odometry.track(features);
    t.stop(odo.wall, odo.cpu);
    t = StepTimer();
    aloam::MappingResult result = mapping.registerFrame(frame);
    t.stop(map.wall, map.cpu);
    to_pose.wall.push_back(nowMs() - pose_start_wall);
    to_pose.cpu.push_back(threadCpuMs() - pose_start_cpu);
    t = StepTimer();
    odometry.indexLast();
    mapping.updateMap(result);
    t.stop(update.wall, update.cpu);
    estimate.push_back(result.pose.isometry());

    if ((i + 1) % every == 0 || i + 1 == w.size())
    {
      // Cost against map extent: the block's mean times beside the map size.
      const auto block_mean = [&](const std::vector<double>& v)
      {
        const std::size_t n = std::min<std::size_t>(v.size(), i + 1 - block_start);
        return n == 0 ? 0.0 : std::accumulate(v.end() - long(n), v.end(), 0.0) / double(n);
      };
      char line[200];
      std::snprintf(line, sizeof(line),
                    "    sweep %6zu  map %8zu points in %4zu cubes  RSS %7.1f MB  mapping %5.1f ms  update %5.1f ms",
                    i + 1, result.map_corners + result.map_surfs, result.cubes, residentMb().first,
                    block_mean(map.wall), block_mean(update.wall));
      growth.emplace_back(line);
      block_start = i + 1;
    }
  }
  double busy_ms = 0.0;
  for (const auto* series : { &reg.wall, &odo.wall, &map.wall, &update.wall })
  {
    busy_ms += std::accumulate(series->begin(), series->end(), 0.0);
  }
  const double seconds = busy_ms / 1e3;

  std::printf("  points per sweep %.0f, rejected sweeps %zu\n", double(points) / double(w.size()), rejected);
  printStage("registration", reg);
  printStage("odometry", odo);
  printStage("mapping", map);
  printStage("-> to the pose", to_pose);
  printStage("map update", update);
  std::printf("  throughput     %.0f sweeps/s, %.2f M points/s (every stage, time spent in them)\n",
              double(w.size()) / seconds, double(points) / seconds / 1e6);
  const auto [rss, peak] = residentMb();
  std::printf("  memory         RSS %.1f MB, process peak %.1f MB\n", rss, peak);
  std::printf("  map size over time:\n");
  for (const std::string& line : growth)
  {
    std::printf("%s\n", line.c_str());
  }
  if (w.truth.size() == estimate.size() && estimate.size() > w.eval.start + 1)
  {
    aloam::eval::Trajectory rebased;
    const Eigen::Isometry3d first = estimate.front().inverse();
    for (const auto& pose : estimate)
    {
      rebased.push_back(first * pose);
    }
    try
    {
      const aloam::eval::EvalResult r = aloam::eval::evaluate(w.truth, rebased, w.eval);
      std::printf("  accuracy       drift %.3f %%, rotation %.3f deg/100 m, ATE %.3f m\n", r.translation_drift_percent,
                  r.rotation_deg_per_100m, r.ate_rmse_m);
    }
    catch (const std::exception& e)
    {
      std::printf("  accuracy       n/a (%s)\n", e.what());
    }
  }
  std::fflush(stdout);
}

/// KITTI sweeps with the settings aloam_offline uses; empty name when the folder is missing.
Workload kittiWorkload(const std::string& dir)
{
  Workload w;
  if (!fs::is_directory(fs::path(dir) / "velodyne"))
  {
    return w;
  }
  w.name = "KITTI 00 frames 0-" + std::to_string(aloam::io::listKittiScans(dir).size() - 1) + " (HDL-64E)";
  w.config = aloam::io::kittiPipelineConfig();
  const std::vector<double> times =
      fs::exists(fs::path(dir) / "times.txt") ? aloam::eval::readTimes(dir + "/times.txt") : std::vector<double>();
  const std::vector<std::string> scans = aloam::io::listKittiScans(dir);
  for (std::size_t i = 0; i < scans.size(); ++i)
  {
    Sweep s;
    aloam::io::readKittiScan(scans[i], s.cloud);
    aloam::io::correctVerticalAngle(s.cloud, aloam::io::kKittiVerticalCorrectionDeg);
    s.stamp = i < times.size() ? times[i] : kSweepPeriod * double(i);
    w.sweeps.push_back(std::move(s));
  }
  const fs::path gt = fs::path(dir) / "poses_kitti_gt.txt";
  const fs::path calib = fs::path(dir) / "calib.txt";
  if (fs::exists(gt) && fs::exists(calib))
  {
    w.truth = aloam::eval::cameraToLidar(aloam::eval::readKittiPoses(gt.string()),
                                         aloam::eval::readKittiCalibTr(calib.string()));
    w.truth.resize(std::min(w.truth.size(), w.sweeps.size()));
    // The official ground truth disagrees with the scans over frames 0-5 (see README).
    w.eval.start = 6;
    w.eval.segment_lengths = { 10, 20, 30, 40, 50, 60, 70 };
  }
  return w;
}

/// `sweeps` sweeps of `sensor` on a car driving the urban street (with a hill) at 10 m/s: every point at
/// its own time (motion distortion), 1 cm range noise, per-point ring and time as drivers give them.
Workload simulatedDrive(const std::string& sensor_name, int sweeps, const std::string& name)
{
  const aloam::SensorModel sensor = *aloam::SensorModel::fromPreset(sensor_name);
  Workload w;
  w.name = name;
  w.config.registration.sensor = sensor;
  w.config.odometry.deskew = true;
  w.has_ring = true;
  w.has_time = true;
  aloam::sim::CarDriveOptions car;
  const aloam::sim::PoseFunction pose_at = aloam::sim::carDrive(car);
  const double length = car.start_x + car.speed * kSweepPeriod * (sweeps + 1) + 100.0;
  std::fprintf(stderr, "aloam_bench: simulating %d %s sweeps (%.1f km of street)...\n", sweeps, sensor_name.c_str(),
               length / 1e3);
  const aloam::sim::Scene scene = aloam::sim::urbanStreetWithHill(kSimSeed, length, car.ground);
  const Eigen::Isometry3d first_end = pose_at(kSweepPeriod);
  for (int k = 0; k < sweeps; ++k)
  {
    const double start = k * kSweepPeriod;
    aloam::sim::ScanOptions scan;
    scan.range_noise_sigma = 0.01;
    scan.seed = kSimSeed * 100003u + static_cast<unsigned>(k);
    Sweep s;
    s.cloud = aloam::sim::scan(
        scene, sensor, [&](double t) { return pose_at(start + t); }, scan);
    if (sensor.ringFieldFromTop())
    {
      // As ouster_ros numbers its rows: from the highest beam down.
      for (aloam::Point& p : s.cloud.points)
      {
        p.ring = static_cast<std::uint16_t>(sensor.numRings() - 1 - p.ring);
      }
    }
    s.stamp = start;
    w.sweeps.push_back(std::move(s));
    w.truth.push_back(first_end.inverse() * pose_at(start + kSweepPeriod));
  }
  w.eval.segment_lengths = { 10, 20, 30, 40, 50, 60, 70, 80, 90 };
  return w;
}

/// A long VLP-16 drive through the endless simulated street (sim::LongDrive): new territory all the
/// way, so the map's eviction keeps it bounded.
Workload longDrive(int sweeps)
{
  const aloam::SensorModel sensor = *aloam::SensorModel::fromPreset("VLP16");
  Workload w;
  w.name = "long simulated drive, 16 beams (VLP16), 10 m/s, " + std::to_string(sweeps / 10) + " s";
  w.config.registration.sensor = sensor;
  w.config.odometry.deskew = true;
  w.has_ring = true;
  w.has_time = true;
  aloam::sim::LongDriveOptions options;
  options.seed = kSimSeed;
  auto drive = std::make_shared<aloam::sim::LongDrive>(options);
  const Eigen::Isometry3d first_end = drive->sweepEndPose(0);
  for (int k = 0; k < sweeps; ++k)
  {
    w.truth.push_back(first_end.inverse() * drive->sweepEndPose(k));
  }
  w.generated_count = static_cast<std::size_t>(sweeps);
  w.generate = [drive, sensor](std::size_t k, Sweep& s)
  {
    s.cloud = drive->sweep(static_cast<long>(k), sensor);
    s.stamp = drive->sweepStamp(static_cast<long>(k));
  };
  w.eval.segment_lengths = { 100, 200, 300, 400, 500, 600, 700, 800 };
  w.eval.step = 10;
  return w;
}

// ---------------------------------------------------------------------------------------------------
// Live mode

sensor_msgs::PointCloud2 toMessage(const aloam::Cloud& cloud)
{
  sensor_msgs::PointCloud2 msg;
  msg.height = 1;
  msg.width = static_cast<std::uint32_t>(cloud.size());
  const char* names[] = { "x", "y", "z", "intensity" };
  for (std::uint32_t i = 0; i < 4; ++i)
  {
    sensor_msgs::PointField f;
    f.name = names[i];
    f.offset = 4 * i;
    f.datatype = sensor_msgs::PointField::FLOAT32;
    f.count = 1;
    msg.fields.push_back(f);
  }
  msg.point_step = 16;
  msg.row_step = msg.point_step * msg.width;
  msg.is_dense = true;
  msg.data.resize(msg.row_step);
  auto* out = reinterpret_cast<float*>(msg.data.data());
  for (const aloam::Point& p : cloud.points)
  {
    *out++ = p.x;
    *out++ = p.y;
    *out++ = p.z;
    *out++ = p.intensity;
  }
  return msg;
}

int runLive(const Options& o)
{
  const Workload w = kittiWorkload(o.kitti);
  if (w.sweeps.empty())
  {
    std::cerr << "aloam_bench --live: no KITTI folder at " << o.kitti << "\n";
    return 2;
  }
  ros::NodeHandle nh;
  ros::Publisher pub = nh.advertise<sensor_msgs::PointCloud2>(o.topic, 2);
  std::mutex mutex;
  std::condition_variable answered_cv;
  std::map<std::uint64_t, double> sent_ms;  // stamp (ns) -> wall time of publishing
  std::map<std::uint64_t, double> latency_ms;
  std::map<std::uint64_t, Eigen::Isometry3d> poses;
  ros::Subscriber sub = nh.subscribe<nav_msgs::Odometry>(
      o.answer, 100,
      [&](const nav_msgs::Odometry::ConstPtr& msg)
      {
        const double now = nowMs();
        std::lock_guard<std::mutex> lock(mutex);
        const std::uint64_t key = msg->header.stamp.toNSec();
        const auto it = sent_ms.find(key);
        if (it != sent_ms.end() && latency_ms.count(key) == 0)
        {
          latency_ms[key] = now - it->second;
          const auto& p = msg->pose.pose;
          Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
          pose.linear() = Eigen::Quaterniond(p.orientation.w, p.orientation.x, p.orientation.y, p.orientation.z)
                              .normalized()
                              .toRotationMatrix();
          pose.translation() = Eigen::Vector3d(p.position.x, p.position.y, p.position.z);
          poses[key] = pose;
        }
        answered_cv.notify_all();
      },
      ros::VoidConstPtr(), ros::TransportHints().tcpNoDelay());
  ros::AsyncSpinner spinner(1);
  spinner.start();

  // Messages are built before the clock starts; each is published at its slot of the sensor rate.
  std::vector<sensor_msgs::PointCloud2> messages;
  for (const Sweep& s : w.sweeps)
  {
    messages.push_back(toMessage(s.cloud));
    messages.back().header.frame_id = "velodyne";
  }
  std::fprintf(stderr, "aloam_bench --live: waiting for a subscriber on %s...\n", pub.getTopic().c_str());
  const ros::WallTime wait_until = ros::WallTime::now() + ros::WallDuration(30.0);
  while (ros::ok() && (pub.getNumSubscribers() == 0 || sub.getNumPublishers() == 0) &&
         ros::WallTime::now() < wait_until)
  {
    ros::WallDuration(0.05).sleep();
  }
  if (pub.getNumSubscribers() == 0)
  {
    std::cerr << "aloam_bench --live: nobody subscribes to " << pub.getTopic() << "\n";
    return 2;
  }
  ros::WallDuration(1.0).sleep();  // let the connections settle
  std::fprintf(stderr, "aloam_bench --live: publishing %zu sweeps at %.1f Hz\n", messages.size(), o.rate);

  const ros::Time base = ros::Time::now();
  const ros::WallTime t0 = ros::WallTime::now();
  std::vector<std::uint64_t> keys;
  for (std::size_t i = 0; i < messages.size() && ros::ok(); ++i)
  {
    const ros::WallTime slot = t0 + ros::WallDuration(double(i) / o.rate);
    const ros::WallDuration wait = slot - ros::WallTime::now();
    if (wait > ros::WallDuration(0.0))
    {
      wait.sleep();
    }
    messages[i].header.stamp = base + ros::Duration(double(i) / o.rate);
    messages[i].header.seq = static_cast<std::uint32_t>(i);
    const std::uint64_t key = messages[i].header.stamp.toNSec();
    keys.push_back(key);
    {
      std::lock_guard<std::mutex> lock(mutex);
      sent_ms[key] = nowMs();
    }
    pub.publish(messages[i]);
  }
  {
    std::unique_lock<std::mutex> lock(mutex);
    answered_cv.wait_for(lock, std::chrono::seconds(3), [&] { return latency_ms.size() == keys.size(); });
  }
  spinner.stop();

  std::vector<double> latencies;
  aloam::eval::Trajectory estimate;
  std::size_t skipped = 0;
  {
    std::lock_guard<std::mutex> lock(mutex);
    for (const std::uint64_t key : keys)
    {
      const auto it = latency_ms.find(key);
      if (it == latency_ms.end())
      {
        ++skipped;
        estimate.push_back(estimate.empty() ? Eigen::Isometry3d::Identity() : estimate.back());
        continue;
      }
      latencies.push_back(it->second);
      estimate.push_back(poses[key]);
    }
  }
  const aloam::eval::SeriesStats stats = summarize(latencies);
  std::printf("\n== live: %s at %.1f Hz, publish -> %s\n", w.name.c_str(), o.rate, o.answer.c_str());
  std::printf("  latency        median %.1f ms, p90 %.1f ms, max %.1f ms, mean %.1f ms\n", stats.median, stats.p90,
              stats.max, stats.mean);
  std::printf("  sweeps         %zu published, %zu answered, %zu skipped\n", keys.size(), latencies.size(), skipped);
  if (w.truth.size() == estimate.size() && skipped == 0)
  {
    const Eigen::Isometry3d first = estimate.front().inverse();
    for (auto& pose : estimate)
    {
      pose = first * pose;
    }
    const aloam::eval::EvalResult r = aloam::eval::evaluate(w.truth, estimate, w.eval);
    std::printf("  accuracy       drift %.3f %%, rotation %.3f deg/100 m, ATE %.3f m\n", r.translation_drift_percent,
                r.rotation_deg_per_100m, r.ate_rmse_m);
  }
  return skipped == 0 ? 0 : 1;
}

bool parse(int argc, char** argv, Options& o)
{
  for (int i = 1; i < argc; ++i)
  {
    const std::string arg = argv[i];
    const auto value = [&]() -> std::string
    {
      if (i + 1 >= argc)
      {
        throw std::invalid_argument(arg + " needs a value");
      }
      return argv[++i];
    };
    if (arg == "--kitti")
      o.kitti = value();
    else if (arg == "--sim-sweeps")
      o.sim_sweeps = std::stoi(value());
    else if (arg == "--long-sweeps")
      o.long_sweeps = std::stoi(value());
    else if (arg == "--only")
      o.only = value();
    else if (arg == "--pace")
      o.pace_hz = std::stod(value());
    else if (arg == "--threads")
      o.threads = std::stoi(value());
    else if (arg == "--live")
      o.live = true;
    else if (arg == "--rate")
      o.rate = std::stod(value());
    else if (arg == "--topic")
      o.topic = value();
    else if (arg == "--answer")
      o.answer = value();
    else if (arg == "-h" || arg == "--help")
      return false;
    else
      throw std::invalid_argument("unknown argument " + arg);
  }
  if (o.sim_sweeps < 2 || o.long_sweeps < 2 || !(o.rate > 0.0))
  {
    throw std::invalid_argument("sweep counts must be >= 2 and the rate positive");
  }
  return true;
}

}  // namespace

int main(int argc, char** argv)
{
  Options o;
  try
  {
    if (!parse(argc, argv, o))
    {
      std::cout << kUsage;
      return 0;
    }
  }
  catch (const std::exception& e)
  {
    std::cerr << "aloam_bench: " << e.what() << "\n" << kUsage;
    return 2;
  }
  if (o.live)
  {
    ros::init(argc, argv, "aloam_bench", ros::init_options::AnonymousName);
    return runLive(o);
  }

  std::printf(
      "aloam_bench: the stages as the nodelets run them (%d thread(s) each%s); 'to the pose' is\n"
      "registration + odometry + mapping (what a robot waits for), 'map update' comes after the pose\n"
      "is published. cpu = CPU time of the stage's own thread.\n",
      o.threads, o.pace_hz > 0.0 ? ", paced" : ", back to back");
  const auto wanted = [&](const std::string& what) { return o.only.empty() || o.only == what; };
  if (wanted("kitti"))
  {
    const Workload kitti = kittiWorkload(o.kitti);
    if (kitti.sweeps.empty())
    {
      std::printf("\n== KITTI: skipped, no sequence at %s\n", o.kitti.c_str());
    }
    else
    {
      runWorkload(kitti, o.pace_hz, o.threads);
    }
  }
  if (wanted("sim"))
  {
    for (const auto& [preset, beams] : std::vector<std::pair<std::string, int>>{
             { "VLP16", 16 }, { "HDL32", 32 }, { "HDL64", 64 }, { "OS1_128", 128 } })
    {
      runWorkload(simulatedDrive(preset, o.sim_sweeps,
                                 "simulated urban drive, " + std::to_string(beams) + " beams (" + preset + ")"),
                  o.pace_hz, o.threads);
    }
  }
  if (wanted("long"))
  {
    runWorkload(longDrive(o.long_sweeps), o.pace_hz, o.threads);
  }
  return 0;
}
