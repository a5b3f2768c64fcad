// aloam_sim: deterministic simulated lidar sequences (rosbag with driver-like PointCloud2 and ground
// truth, optionally a KITTI-layout folder) from the synthetic scenes and trajectories.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <geometry_msgs/TransformStamped.h>
#include <nav_msgs/Odometry.h>
#include <rosbag/bag.h>
#include <sensor_msgs/PointCloud2.h>
#include <sensor_msgs/PointField.h>
#include <tf2_msgs/TFMessage.h>

#include "aloam_nodelet/core/sensor_model.h"
#include "aloam_nodelet/eval/trajectory_io.h"
#include "aloam_nodelet/sim/families.h"
#include "aloam_nodelet/sim/raycaster.h"
#include "aloam_nodelet/sim/scenes_extra.h"
#include "aloam_nodelet/sim/trajectories.h"

namespace fs = std::filesystem;

namespace
{
constexpr double kPi = 3.14159265358979323846;
constexpr double kStartStamp = 1000.0;         // s, header stamp of the first sweep
constexpr double kStartAzimuth = kPi;          // the sweep is cut behind the sensor
constexpr double kStraightSpeed = 5.0;         // m/s
constexpr double kSceneMargin = 150.0;         // m of street beyond the end of the trajectory
constexpr double kCorridorCarWeave = 0.3;      // m, lateral weave of a car in the corridor
constexpr double kTunnelCarWeave = 0.5;        // m, lateral weave of a car in the tunnel
constexpr double kOfficeStartX = 2.0;          // m, start of the walks along the office's first corridor
constexpr double kUrbanHandHeldStartX = 10.0;  // m
constexpr double kVelocityStep = 1e-3;         // s, central differences of the ground-truth twist
constexpr unsigned kSweepSeedStride = 100003U;
constexpr int kProgressEvery = 10;  // sweeps
constexpr const char* kCloudTopic = "velodyne_points";
constexpr const char* kTruthTopic = "ground_truth";
constexpr const char* kTfTopic = "/tf";
constexpr const char* kWorldFrame = "world";

const char* const kUsage =
    "usage: aloam_sim --sensor PRESET --scene SCENE --trajectory TRAJECTORY --duration SECONDS --seed N\n"
    "                 [--noise SIGMA_M] [--dropout P] [--keep-every N] --bag OUT.bag [--kitti OUT_DIR]\n"
    "       aloam_sim --sensor PRESET --family FAMILY --duration SECONDS --seed N [same options]\n"
    "  --family FAMILY    draw the scene and the motion from a family's ranges by --seed (printed as one\n"
    "                     `draw: family=... key=value ...` line); FAMILY is one of\n"
    "                     corridor   1.8-4 m wide, 50-300 m, end walls near / far / open, doors or niches\n"
    "                                every 5-100 m, sometimes one turn; hand-held\n"
    "                     tunnel     5-10 m wide, sparse niches / lights / standpipes; car 5-20 m/s\n"
    "                     office     L of two corridors with doors, niches and cabinets; walk around it\n"
    "                     stairwell  one flight of 10-20 risers; hand-held climb\n"
    "                     urban      street with buildings, cars, poles, trees, a hill; car or hand-held\n"
    "                     field      open ground with 0-10 objects; car or hand-held\n"
    "                     corridor_issue23  the corridor of issue 23 (2.5 x 200 m, closed, six 0.25 m door\n"
    "                                recesses from 40 m ahead; 1.4 m/s, 10 deg sway, 90 deg/s bursts)\n"
    "                     loop_block  a car (6-10 m/s) round an urban block 1.5-2 times; the block's\n"
    "                                perimeter (200-600 m) follows from the speed, laps and --duration\n"
    "                     loop_eight  a car on a figure-eight round two blocks touching at a crossing\n"
    "                                (passed eastbound and southbound), 1.1-1.5 laps of 400-900 m\n"
    "                     loop_floor  a walk (1.2-1.5 m/s, sway, bobbing) 1.2-1.5 times round the ring\n"
    "                                corridor of a building floor (40-200 m) with doors, niches, rooms\n"
    "                     loop_repetitive  a car in a grid of identical blocks every 50-80 m: round a\n"
    "                                loop of blocks (a true revisit) or a serpentine (none), drawn\n"
    "                     The loop families loop in 60-120 s; shorter draws loop less than once.\n"
    "                     Hand-held motions: sway 0-15 deg, yaw bursts 0-120 deg/s at random times, maybe a\n"
    "                     start from rest and stops. The seed also seeds the noise.\n"
    "  --sensor PRESET    VLP16, HDL32, HDL64, VLP32C (Velodyne layout), OS1_64, OS0_64, OS1_128 (Ouster layout)\n"
    "  --scene SCENE      urban     street with buildings, parked cars, poles, trees and a hill\n"
    "                     corridor  straight indoor corridor 2.5 m wide, 100 m long, doors and niches\n"
    "                     field     open ground with a handful of objects\n"
    "                     office    L-shaped corridor 2.5 m wide (16 m, a 90 deg left turn, 24 m) with doors,\n"
    "                               niches, cabinets, floor and ceiling\n"
    "                     tunnel    road tunnel 6 m wide with an arched roof, a niche, light or standpipe\n"
    "                               every 10-20 m\n"
    "                     stairs    stairwell with one flight climbing 2.98 m over 4.5 m\n"
    "  --trajectory TRAJECTORY\n"
    "                     car              10 m/s along the scene with lateral weaves (tunnel: +-0.5 m)\n"
    "                     straight         5 m/s on a straight line\n"
    "                     handheld         1.4 m/s walk with 90 deg/s yaw bursts every 4 s (stairs: a\n"
    "                                      0.6 m/s climb with 45 deg/s look-arounds)\n"
    "                     handheld_bursts  walk with 120 deg/s yaw bursts every 3 s and a full stop (1 s\n"
    "                                      standing still) every 6 s\n"
    "                     handheld_turn    office only: walk along the first corridor, turn the corner\n"
    "                                      and walk on along the second\n"
    "  --noise SIGMA_M    Gaussian range noise in metres (default 0.01)\n"
    "  --dropout P        probability of dropping a return (default 0)\n"
    "  --keep-every N     publish only every N-th sweep (like a throttled topic): stamps N sweep periods\n"
    "                     apart, each sweep still covering one period of motion from its own start, ground\n"
    "                     truth for the published sweeps only (default 1)\n"
    "  --kitti OUT_DIR    also write OUT_DIR/velodyne/%06d.bin, times.txt and poses.txt (published sweeps)\n";

struct Options
{
  std::string sensor;
  std::string scene;
  std::string trajectory;
  double duration = 0.0;
  unsigned seed = 0;
  bool has_seed = false;
  double noise = 0.01;
  double dropout = 0.0;
  int keep_every = 1;
  std::string bag;
  std::string kitti;
  std::string family;
};

Options parseArguments(int argc, char** argv)
{
  Options o;
  for (int i = 1; i < argc; ++i)
  {
    const std::string arg = argv[i];
    const auto value = [&]() -> std::string
    {
      if (i + 1 >= argc)
      {
        throw std::invalid_argument("missing value after " + arg);
      }
      return argv[++i];
    };
    const auto number = [&]()
    {
      const std::string text = value();
      std::size_t used = 0;
      const double parsed = std::stod(text, &used);
      if (used != text.size() || !std::isfinite(parsed))
      {
        throw std::invalid_argument("bad number for " + arg + ": " + text);
      }
      return parsed;
    };
    if (arg == "--sensor")
      o.sensor = value();
    else if (arg == "--scene")
      o.scene = value();
    else if (arg == "--trajectory")
      o.trajectory = value();
    else if (arg == "--family")
      o.family = value();
    else if (arg == "--duration")
      o.duration = number();
    else if (arg == "--seed")
    {
      const double seed = number();
      if (seed < 0.0 || seed > std::numeric_limits<unsigned>::max() || seed != std::floor(seed))
      {
        throw std::invalid_argument("--seed must be a non-negative integer");
      }
      o.seed = static_cast<unsigned>(seed);
      o.has_seed = true;
    }
    else if (arg == "--noise")
      o.noise = number();
    else if (arg == "--dropout")
      o.dropout = number();
    else if (arg == "--keep-every")
    {
      const double keep = number();
      if (keep < 1.0 || keep > 1000.0 || keep != std::floor(keep))
      {
        throw std::invalid_argument("--keep-every must be an integer in [1, 1000]");
      }
      o.keep_every = static_cast<int>(keep);
    }
    else if (arg == "--bag")
      o.bag = value();
    else if (arg == "--kitti")
      o.kitti = value();
    else if (arg == "-h" || arg == "--help")
    {
      std::cout << kUsage;
      std::exit(0);
    }
    else
      throw std::invalid_argument("unknown argument " + arg);
  }
  if (!o.family.empty())
  {
    if (!o.scene.empty() || !o.trajectory.empty())
    {
      throw std::invalid_argument("--family replaces --scene and --trajectory");
    }
    if (!aloam::sim::familyFromName(o.family))
    {
      throw std::invalid_argument("unknown family " + o.family);
    }
    if (o.sensor.empty() || o.bag.empty() || !o.has_seed)
    {
      throw std::invalid_argument("--sensor, --family, --duration, --seed and --bag are required");
    }
  }
  else if (o.sensor.empty() || o.scene.empty() || o.trajectory.empty() || o.bag.empty() || !o.has_seed)
  {
    throw std::invalid_argument("--sensor, --scene, --trajectory, --duration, --seed and --bag are required");
  }
  if (!(o.duration > 0.0))
  {
    throw std::invalid_argument("--duration must be positive");
  }
  if (o.noise < 0.0 || o.dropout < 0.0 || o.dropout >= 1.0)
  {
    throw std::invalid_argument("--noise must be >= 0 and --dropout in [0, 1)");
  }
  if (!o.family.empty())
  {
    return o;
  }
  const std::vector<std::string> scenes = { "urban", "corridor", "field", "office", "tunnel", "stairs" };
  if (std::find(scenes.begin(), scenes.end(), o.scene) == scenes.end())
  {
    throw std::invalid_argument("unknown scene " + o.scene);
  }
  const std::vector<std::string> trajectories = { "car", "handheld", "straight", "handheld_bursts", "handheld_turn" };
  if (std::find(trajectories.begin(), trajectories.end(), o.trajectory) == trajectories.end())
  {
    throw std::invalid_argument("unknown trajectory " + o.trajectory);
  }
  if (o.trajectory == "handheld_turn" && o.scene != "office")
  {
    throw std::invalid_argument("--trajectory handheld_turn needs --scene office");
  }
  return o;
}

bool isOuster(const std::string& preset)
{
  return preset.rfind("OS", 0) == 0;
}

/// The ground profile of a scene (the urban street has a hill, the stairs a flight, the others are flat).
aloam::sim::GroundProfile groundOf(const std::string& scene)
{
  if (scene == "urban")
  {
    return aloam::sim::GroundProfile();
  }
  if (scene == "stairs")
  {
    return aloam::sim::stairsProfile();
  }
  return aloam::sim::GroundProfile::flat();
}

struct TrajectorySetup
{
  aloam::sim::PoseFunction pose_at;
  double start_x = 0.0;
  double speed = 0.0;
};

TrajectorySetup makeTrajectory(const Options& o)
{
  const aloam::sim::GroundProfile ground = groundOf(o.scene);
  TrajectorySetup setup;
  if (o.trajectory == "car")
  {
    aloam::sim::CarDriveOptions car;
    car.ground = ground;
    if (o.scene == "corridor" || o.scene == "office")
    {
      car.start_x = aloam::sim::HandHeldOptions().start_x;
      car.weave_amplitude_m = kCorridorCarWeave;
    }
    else if (o.scene == "tunnel")
    {
      car.weave_amplitude_m = kTunnelCarWeave;
    }
    setup.pose_at = aloam::sim::carDrive(car);
    setup.start_x = car.start_x;
    setup.speed = car.speed;
  }
  else if (o.trajectory == "handheld" || o.trajectory == "handheld_bursts")
  {
    aloam::sim::HandHeldOptions walk;
    if (o.scene == "stairs")
    {
      walk = aloam::sim::stairsWalkOptions();
    }
    if (o.trajectory == "handheld_bursts")
    {
      const aloam::sim::HandHeldOptions bursts = aloam::sim::handHeldBurstsOptions();
      walk.burst_rate_rad_s = bursts.burst_rate_rad_s;
      walk.burst_interval_s = bursts.burst_interval_s;
      walk.stop_interval_s = bursts.stop_interval_s;
      walk.first_stop_s = bursts.first_stop_s;
    }
    walk.ground = ground;
    if (o.scene == "urban")
    {
      walk.start_x = kUrbanHandHeldStartX;
    }
    else if (o.scene == "office")
    {
      walk.start_x = kOfficeStartX;
    }
    setup.pose_at = aloam::sim::handHeld(walk);
    setup.start_x = walk.start_x;
    setup.speed = walk.speed;
  }
  else if (o.trajectory == "handheld_turn")
  {
    const aloam::sim::TurnWalkOptions walk = aloam::sim::officeTurnWalk();
    setup.pose_at = aloam::sim::handHeldTurn(walk);
    setup.start_x = walk.start_xy.x();
    setup.speed = walk.speed;
  }
  else
  {
    aloam::sim::StraightOptions line;
    line.speed = kStraightSpeed;
    line.ground = ground;
    if (o.scene == "corridor" || o.scene == "office")
    {
      line.start_x = aloam::sim::HandHeldOptions().start_x;
    }
    else if (o.scene == "stairs")
    {
      line.start_x = aloam::sim::stairsWalkOptions().start_x;
    }
    setup.pose_at = aloam::sim::straight(line);
    setup.start_x = line.start_x;
    setup.speed = line.speed;
  }
  return setup;
}

aloam::sim::Scene makeScene(const Options& o, const TrajectorySetup& trajectory)
{
  const double length = trajectory.start_x + trajectory.speed * o.duration + kSceneMargin;
  if (o.scene == "urban")
  {
    return aloam::sim::urbanStreetWithHill(o.seed, length, groundOf(o.scene));
  }
  if (o.scene == "corridor")
  {
    const aloam::sim::CorridorOptions corridor;
    const double end_x = trajectory.start_x + trajectory.speed * o.duration;
    if (end_x > corridor.length_m - 1.0)
    {
      std::cerr << "warning: the trajectory reaches x = " << end_x << " m, beyond the " << corridor.length_m
                << " m corridor\n";
    }
    return aloam::sim::corridorScene(o.seed, corridor);
  }
  const Eigen::Vector3d end = trajectory.pose_at(o.duration).translation();
  if (o.scene == "office")
  {
    const aloam::sim::OfficeOptions office;
    const double half_width = 0.5 * office.width_m;
    const bool in_first = end.x() > 0.0 && end.x() < office.first_length_m && std::abs(end.y()) < half_width;
    const bool in_second = end.x() > office.first_length_m - office.width_m && end.x() < office.first_length_m &&
                           end.y() > -half_width && end.y() < office.secondEndY();
    if (!in_first && !in_second)
    {
      std::cerr << "warning: the trajectory ends at (" << end.x() << ", " << end.y() << ") m, outside the office\n";
    }
    return aloam::sim::officeScene(o.seed, office);
  }
  if (o.scene == "tunnel")
  {
    aloam::sim::TunnelOptions tunnel;
    tunnel.length_m = length;
    return aloam::sim::tunnelScene(o.seed, tunnel);
  }
  if (o.scene == "stairs")
  {
    const aloam::sim::StairsOptions stairs;
    if (end.x() > stairs.run() + stairs.top_landing_m - 0.5)
    {
      std::cerr << "warning: the trajectory reaches x = " << end.x() << " m, beyond the stairwell\n";
    }
    return aloam::sim::stairsScene(o.seed, stairs);
  }
  return aloam::sim::openFieldScene(o.seed, length);
}

sensor_msgs::PointField makeField(const std::string& name, std::uint32_t offset, std::uint8_t datatype)
{
  sensor_msgs::PointField field;
  field.name = name;
  field.offset = offset;
  field.datatype = datatype;
  field.count = 1;
  return field;
}

template <typename T>
void putValue(std::uint8_t* base, std::uint32_t offset, T value)
{
  std::memcpy(base + offset, &value, sizeof(T));
}

/// velodyne_pointcloud's XYZIRT layout: x y z intensity (float32), ring (uint16), time (float32 s).
void toVelodyneMsg(const aloam::Cloud& cloud, sensor_msgs::PointCloud2& msg)
{
  constexpr std::uint32_t kX = 0, kY = 4, kZ = 8, kIntensity = 12, kRing = 16, kTime = 18, kStep = 22;
  msg.fields = { makeField("x", kX, sensor_msgs::PointField::FLOAT32),
                 makeField("y", kY, sensor_msgs::PointField::FLOAT32),
                 makeField("z", kZ, sensor_msgs::PointField::FLOAT32),
                 makeField("intensity", kIntensity, sensor_msgs::PointField::FLOAT32),
                 makeField("ring", kRing, sensor_msgs::PointField::UINT16),
                 makeField("time", kTime, sensor_msgs::PointField::FLOAT32) };
  msg.height = 1;
  msg.width = static_cast<std::uint32_t>(cloud.size());
  msg.point_step = kStep;
  msg.row_step = kStep * msg.width;
  msg.is_bigendian = false;
  msg.is_dense = true;
  msg.data.assign(static_cast<std::size_t>(msg.row_step), 0);
  for (std::size_t i = 0; i < cloud.size(); ++i)
  {
    const aloam::Point& p = cloud.points[i];
    std::uint8_t* base = msg.data.data() + i * kStep;
    putValue(base, kX, p.x);
    putValue(base, kY, p.y);
    putValue(base, kZ, p.z);
    putValue(base, kIntensity, p.intensity);
    putValue(base, kRing, p.ring);
    putValue(base, kTime, p.time);
  }
}

/// ouster_ros-like organized layout: rows = beams (row 0 = highest beam, ring = row), columns in
/// firing order; x y z intensity (float32), t (uint32 ns since the sweep start), ring (uint16).
/// Cells without a return are NaN points (with their t and ring).
void toOusterMsg(const aloam::Cloud& cloud, const aloam::SensorModel& sensor, sensor_msgs::PointCloud2& msg)
{
  constexpr std::uint32_t kX = 0, kY = 4, kZ = 8, kIntensity = 16, kT = 20, kRing = 24, kStep = 32;
  constexpr double kNanoseconds = 1e9;
  msg.fields = { makeField("x", kX, sensor_msgs::PointField::FLOAT32),
                 makeField("y", kY, sensor_msgs::PointField::FLOAT32),
                 makeField("z", kZ, sensor_msgs::PointField::FLOAT32),
                 makeField("intensity", kIntensity, sensor_msgs::PointField::FLOAT32),
                 makeField("t", kT, sensor_msgs::PointField::UINT32),
                 makeField("ring", kRing, sensor_msgs::PointField::UINT16) };
  const int rows = sensor.numRings();
  const int columns = sensor.columns();
  const double period = sensor.scanPeriod();
  msg.height = static_cast<std::uint32_t>(rows);
  msg.width = static_cast<std::uint32_t>(columns);
  msg.point_step = kStep;
  msg.row_step = kStep * msg.width;
  msg.is_bigendian = false;
  msg.is_dense = false;
  msg.data.assign(static_cast<std::size_t>(msg.row_step) * msg.height, 0);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (int row = 0; row < rows; ++row)
  {
    for (int column = 0; column < columns; ++column)
    {
      std::uint8_t* base = msg.data.data() + (static_cast<std::size_t>(row) * columns + column) * kStep;
      putValue(base, kX, nan);
      putValue(base, kY, nan);
      putValue(base, kZ, nan);
      putValue(base, kIntensity, 0.0f);
      putValue(base, kT, static_cast<std::uint32_t>(std::lround(column * period / columns * kNanoseconds)));
      putValue(base, kRing, static_cast<std::uint16_t>(row));
    }
  }
  for (const aloam::Point& p : cloud.points)
  {
    const long column = std::lround(static_cast<double>(p.time) * columns / period);
    const int row = rows - 1 - static_cast<int>(p.ring);
    if (column < 0 || column >= columns || row < 0 || row >= rows)
    {
      continue;
    }
    std::uint8_t* base = msg.data.data() + (static_cast<std::size_t>(row) * columns + column) * kStep;
    putValue(base, kX, p.x);
    putValue(base, kY, p.y);
    putValue(base, kZ, p.z);
    putValue(base, kIntensity, p.intensity);
  }
}

geometry_msgs::Transform toTransformMsg(const Eigen::Isometry3d& pose)
{
  geometry_msgs::Transform msg;
  const Eigen::Quaterniond q(pose.linear());
  msg.translation.x = pose.translation().x();
  msg.translation.y = pose.translation().y();
  msg.translation.z = pose.translation().z();
  msg.rotation.x = q.x();
  msg.rotation.y = q.y();
  msg.rotation.z = q.z();
  msg.rotation.w = q.w();
  return msg;
}

/// Ground truth at time t: pose world <- sensor and twist in the sensor frame (central differences).
nav_msgs::Odometry makeOdometry(const aloam::sim::PoseFunction& pose_at, double t, const ros::Time& stamp,
                                const std::string& child_frame)
{
  const Eigen::Isometry3d pose = pose_at(t);
  const Eigen::Isometry3d before = pose_at(t - kVelocityStep);
  const Eigen::Isometry3d after = pose_at(t + kVelocityStep);
  const Eigen::Vector3d linear_world = (after.translation() - before.translation()) / (2.0 * kVelocityStep);
  const Eigen::AngleAxisd delta(before.linear().transpose() * after.linear());
  const Eigen::Vector3d angular_body = delta.axis() * delta.angle() / (2.0 * kVelocityStep);
  const Eigen::Vector3d linear_body = pose.linear().transpose() * linear_world;

  nav_msgs::Odometry msg;
  msg.header.stamp = stamp;
  msg.header.frame_id = kWorldFrame;
  msg.child_frame_id = child_frame;
  const geometry_msgs::Transform transform = toTransformMsg(pose);
  msg.pose.pose.position.x = transform.translation.x;
  msg.pose.pose.position.y = transform.translation.y;
  msg.pose.pose.position.z = transform.translation.z;
  msg.pose.pose.orientation = transform.rotation;
  msg.twist.twist.linear.x = linear_body.x();
  msg.twist.twist.linear.y = linear_body.y();
  msg.twist.twist.linear.z = linear_body.z();
  msg.twist.twist.angular.x = angular_body.x();
  msg.twist.twist.angular.y = angular_body.y();
  msg.twist.twist.angular.z = angular_body.z();
  return msg;
}

void writeKittiScan(const fs::path& path, const aloam::Cloud& cloud)
{
  std::vector<float> values;
  values.reserve(cloud.size() * 4);
  for (const aloam::Point& p : cloud.points)
  {
    values.push_back(p.x);
    values.push_back(p.y);
    values.push_back(p.z);
    values.push_back(static_cast<float>(p.intensity / aloam::sim::kMaxIntensity));
  }
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(values.data()), static_cast<std::streamsize>(values.size() * sizeof(float)));
  if (!out)
  {
    throw std::runtime_error("cannot write " + path.string());
  }
}

int run(const Options& o)
{
  const std::optional<aloam::SensorModel> sensor = aloam::SensorModel::fromPreset(o.sensor);
  if (!sensor)
  {
    throw std::invalid_argument("unknown sensor preset " + o.sensor);
  }
  const bool ouster = isOuster(o.sensor);
  const std::string frame = ouster ? "os_sensor" : "velodyne";
  const double period = sensor->scanPeriod();
  const int sweeps = static_cast<int>(std::floor(o.duration / period + 1e-9));
  if (sweeps < 1)
  {
    throw std::invalid_argument("--duration is shorter than one sweep");
  }
  // Sweeps k = 0, N, 2N, ... are published (a throttled topic); the others are not even cast.
  const std::vector<double> starts = aloam::sim::publishedSweepStarts(o.duration, period, o.keep_every);
  const int published = static_cast<int>(starts.size());

  const auto build_start = std::chrono::steady_clock::now();
  std::optional<aloam::sim::FamilyDraw> draw;
  if (!o.family.empty())
  {
    draw = aloam::sim::drawFamily(*aloam::sim::familyFromName(o.family), o.seed, o.duration);
    std::printf("draw: %s\n", draw->describe().c_str());
    std::fflush(stdout);
  }
  TrajectorySetup trajectory;
  if (draw)
  {
    trajectory.pose_at = aloam::sim::familyMotion(*draw);
  }
  else
  {
    trajectory = makeTrajectory(o);
  }
  const aloam::sim::Scene scene = draw ? aloam::sim::familyScene(*draw) : makeScene(o, trajectory);
  const std::string scene_name = draw ? o.family : o.scene;
  const std::string trajectory_name = draw ? "drawn" : o.trajectory;
  const double build_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - build_start).count();
  std::cerr << "aloam_sim: " << o.sensor << ", scene " << scene_name << " (" << scene.size() << " primitives, built in "
            << build_seconds << " s), trajectory " << trajectory_name << ", " << sweeps << " sweeps";
  if (o.keep_every > 1)
  {
    std::cerr << ", every " << o.keep_every << "th published (" << published << ")";
  }
  std::cerr << "\n";

  fs::path kitti_dir;
  std::ofstream times;
  if (!o.kitti.empty())
  {
    kitti_dir = o.kitti;
    fs::create_directories(kitti_dir / "velodyne");
    times.open(kitti_dir / "times.txt");
    if (!times)
    {
      throw std::runtime_error("cannot write " + (kitti_dir / "times.txt").string());
    }
  }

  rosbag::Bag bag(o.bag, rosbag::bagmode::Write);
  aloam::eval::Trajectory truth;
  const Eigen::Isometry3d first_end = trajectory.pose_at(period);
  std::size_t total_points = 0;
  double scan_seconds = 0.0;
  const auto loop_start = std::chrono::steady_clock::now();
  int written = 0;
  double path_length = 0.0;
  Eigen::Vector3d previous_position = trajectory.pose_at(0.0).translation();
  for (const double start : starts)
  {
    const int k = static_cast<int>(std::lround(start / period));
    aloam::sim::ScanOptions scan_options;
    scan_options.range_noise_sigma = o.noise;
    scan_options.dropout_probability = o.dropout;
    scan_options.start_azimuth_rad = kStartAzimuth;
    scan_options.seed = o.seed * kSweepSeedStride + static_cast<unsigned>(k);
    const auto scan_start = std::chrono::steady_clock::now();
    const aloam::Cloud cloud = aloam::sim::scan(
        scene, *sensor, [&](double t) { return trajectory.pose_at(start + t); }, scan_options);
    scan_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - scan_start).count();
    total_points += cloud.size();

    const ros::Time sweep_stamp(kStartStamp + start);
    const ros::Time end_stamp(kStartStamp + start + period);
    sensor_msgs::PointCloud2 msg;
    if (ouster)
    {
      toOusterMsg(cloud, *sensor, msg);
    }
    else
    {
      toVelodyneMsg(cloud, msg);
    }
    msg.header.stamp = sweep_stamp;
    msg.header.frame_id = frame;
    msg.header.seq = static_cast<std::uint32_t>(written);
    // Drivers publish a sweep once it is complete: record everything at the sweep end.
    bag.write(kCloudTopic, end_stamp, msg);

    const nav_msgs::Odometry odometry = makeOdometry(trajectory.pose_at, start + period, end_stamp, frame);
    bag.write(kTruthTopic, end_stamp, odometry);
    geometry_msgs::TransformStamped transform;
    transform.header.stamp = end_stamp;
    transform.header.frame_id = kWorldFrame;
    transform.child_frame_id = frame;
    transform.transform = toTransformMsg(trajectory.pose_at(start + period));
    tf2_msgs::TFMessage tf;
    tf.transforms.push_back(transform);
    bag.write(kTfTopic, end_stamp, tf);

    truth.push_back(first_end.inverse() * trajectory.pose_at(start + period));
    const Eigen::Vector3d position = trajectory.pose_at(start + period).translation();
    path_length += (position - previous_position).norm();
    previous_position = position;
    if (!kitti_dir.empty())
    {
      char name[32];
      std::snprintf(name, sizeof(name), "%06d.bin", written);
      writeKittiScan(kitti_dir / "velodyne" / name, cloud);
      char line[64];
      std::snprintf(line, sizeof(line), "%.6e\n", start);
      times << line;
    }
    if ((written + 1) % kProgressEvery == 0 || written + 1 == published)
    {
      std::cerr << "\r  sweep " << (written + 1) << "/" << published << std::flush;
    }
    ++written;
  }
  std::cerr << "\n";
  bag.close();
  if (!kitti_dir.empty())
  {
    times.close();
    aloam::eval::writeKittiPoses((kitti_dir / "poses.txt").string(), truth);
  }
  const double loop_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - loop_start).count();
  std::printf("aloam_sim summary\n");
  std::printf("  sensor %s (%d rings x %d columns, %.3f s), scene %s (%zu primitives), trajectory %s, seed %u\n",
              o.sensor.c_str(), sensor->numRings(), sensor->columns(), period, scene_name.c_str(), scene.size(),
              trajectory_name.c_str(), o.seed);
  std::printf(
      "  sweeps %d (every %d of %d), points %zu (%.0f per sweep), path %.2f m (polyline of the published poses), noise "
      "%.3f m, dropout %.3f\n",
      published, o.keep_every, sweeps, total_points, static_cast<double>(total_points) / published, path_length,
      o.noise, o.dropout);
  std::printf("  bag %s (%.1f MB)%s%s\n", o.bag.c_str(), static_cast<double>(fs::file_size(o.bag)) / 1e6,
              kitti_dir.empty() ? "" : ", kitti ", kitti_dir.string().c_str());
  std::printf("  ray casting %.2f sweeps/s (%.3f s), overall %.2f sweeps/s (%.3f s)\n", published / scan_seconds,
              scan_seconds, published / loop_seconds, loop_seconds);
  return 0;
}
}  // namespace

int main(int argc, char** argv)
{
  Options options;
  try
  {
    options = parseArguments(argc, argv);
  }
  catch (const std::exception& e)
  {
    std::cerr << "aloam_sim: " << e.what() << "\n" << kUsage;
    return 2;
  }
  try
  {
    return run(options);
  }
  catch (const std::exception& e)
  {
    std::cerr << "aloam_sim: " << e.what() << "\n";
    return 1;
  }
}
