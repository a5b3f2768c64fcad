// Shared helpers of the LOAM core unit tests: synthetic street sweeps, poses and error measures.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>
#include <functional>
#include <string>
#include <unordered_map>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "aloam_nodelet/core/feature_set.h"
#include "aloam_nodelet/core/point_types.h"
#include "aloam_nodelet/core/pose.h"
#include "aloam_nodelet/core/sensor_model.h"
#include "aloam_nodelet/sim/raycaster.h"
#include "aloam_nodelet/sim/scene.h"

namespace aloam
{
namespace test_support
{
constexpr double kDegToRad = M_PI / 180.0;
constexpr double kRadToDeg = 180.0 / M_PI;
/// Seed and length of the street every test drives in.
constexpr unsigned kStreetSeed = 11;
constexpr double kStreetLength = 400.0;
/// Height of the sensor above the street centreline.
constexpr double kSensorHeight = 1.8;
/// Sweep period of every simulated preset.
constexpr double kSweepPeriod = 0.1;

/// The street scene, built once per process (construction is deterministic; queries are const).
inline const sim::Scene& streetScene()
{
  static const sim::Scene scene = sim::Scene::urbanStreet(kStreetSeed, kStreetLength);
  return scene;
}

/// A sensor preset that must exist.
inline SensorModel preset(const std::string& name)
{
  const std::optional<SensorModel> model = SensorModel::fromPreset(name);
  if (!model)
  {
    ADD_FAILURE() << "unknown sensor preset " << name;
    return SensorModel::uniform(16, -15.0, 15.0);
  }
  return *model;
}

/// world <- sensor from a position and roll / pitch / yaw (applied as yaw * pitch * roll).
inline Eigen::Isometry3d poseFrom(double x, double y, double z, double yaw, double pitch = 0.0, double roll = 0.0)
{
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translation() = Eigen::Vector3d(x, y, z);
  pose.linear() =
      (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
       Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
          .toRotationMatrix();
  return pose;
}

/// A sensor on the street centreline at distance `x` along it, heading along +x.
inline Eigen::Isometry3d streetPose(double x, double y = 0.0, double yaw = 0.0)
{
  return poseFrom(x, y, kSensorHeight, yaw);
}

/// One noise-free sweep of the street from a fixed pose (points in the sensor frame, ring and time set).
inline Cloud staticSweep(const SensorModel& sensor, const Eigen::Isometry3d& pose,
                         std::vector<int>* surface_ids = nullptr, double start_azimuth = 0.0)
{
  sim::ScanOptions options;
  options.start_azimuth_rad = start_azimuth;
  return sim::scanStatic(streetScene(), sensor, pose, options, surface_ids);
}

/// One noise-free sweep of the street from a moving sensor (real motion distortion).
inline Cloud movingSweep(const SensorModel& sensor, const sim::PoseFunction& pose_at)
{
  return sim::scan(streetScene(), sensor, pose_at, sim::ScanOptions{});
}

/// A sensor trajectory: world <- sensor at an absolute time (s).
using Trajectory = std::function<Eigen::Isometry3d(double)>;

/// Drive along the street centreline at `speed` from `start_x`, then a lane change of `offset` metres
/// (a half cosine in y over `change_duration` seconds starting at `change_start`); the heading follows
/// the path tangent.
inline Trajectory laneChangeDrive(double start_x, double speed, double change_start, double change_duration,
                                  double offset)
{
  return [=](double time)
  {
    double y = 0.0, dy = 0.0;
    if (time >= change_start + change_duration)
    {
      y = offset;
    }
    else if (time > change_start)
    {
      const double phase = M_PI * (time - change_start) / change_duration;
      y = 0.5 * offset * (1.0 - std::cos(phase));
      dy = 0.5 * offset * M_PI / change_duration * std::sin(phase);
    }
    return poseFrom(start_x + speed * time, y, kSensorHeight, std::atan2(dy, speed));
  };
}

/// Sweep `k` of a drive (it covers [k T, (k + 1) T)): with real motion distortion, or, if `distorted` is
/// false, taken entirely from the pose at the sweep end.
inline Cloud driveSweep(const SensorModel& sensor, const Trajectory& drive, int k, bool distorted)
{
  const double start = k * sensor.scanPeriod();
  if (!distorted)
  {
    return staticSweep(sensor, drive(start + sensor.scanPeriod()));
  }
  return movingSweep(sensor, [&](double t) { return drive(start + t); });
}

/// A point with the given coordinates and fields.
inline Point makePoint(double x, double y, double z, std::uint16_t ring = 0, float intensity = 0.0f, float time = 0.0f)
{
  Point p;
  p.x = static_cast<float>(x);
  p.y = static_cast<float>(y);
  p.z = static_cast<float>(z);
  p.intensity = intensity;
  p.time = time;
  p.ring = ring;
  return p;
}

/// A cloud holding `points` (unorganized).
inline Cloud cloudOf(const std::vector<Point>& points)
{
  Cloud c;
  for (const Point& p : points)
  {
    c.push_back(p);
  }
  return c;
}

inline Pose toPose(const Eigen::Isometry3d& iso)
{
  return Pose(Eigen::Quaterniond(iso.rotation()).normalized(), iso.translation());
}

/// Distance between the translations of two poses (m).
inline double translationError(const Pose& estimate, const Pose& truth)
{
  return (estimate.t - truth.t).norm();
}

/// Angle of the rotation between two poses (degrees).
inline double rotationErrorDeg(const Pose& estimate, const Pose& truth)
{
  return Eigen::AngleAxisd((estimate.q.normalized().conjugate() * truth.q.normalized()).normalized()).angle() *
         kRadToDeg;
}

/// Key of a point by the exact bits of its coordinates (the core copies points without changing them).
struct PointKey
{
  std::uint32_t x = 0, y = 0, z = 0;

  bool operator==(const PointKey& o) const { return x == o.x && y == o.y && z == o.z; }
};

struct PointKeyHash
{
  std::size_t operator()(const PointKey& k) const
  {
    return (static_cast<std::size_t>(k.x) * 73856093u) ^ (static_cast<std::size_t>(k.y) * 19349663u) ^
           (static_cast<std::size_t>(k.z) * 83492791u);
  }
};

inline PointKey keyOf(const Point& p)
{
  PointKey k;
  std::memcpy(&k.x, &p.x, sizeof(float));
  std::memcpy(&k.y, &p.y, sizeof(float));
  std::memcpy(&k.z, &p.z, sizeof(float));
  return k;
}

/// Index of every point of `cloud` by its coordinates (later duplicates are ignored).
inline std::unordered_map<PointKey, std::size_t, PointKeyHash> indexByCoordinates(const Cloud& cloud)
{
  std::unordered_map<PointKey, std::size_t, PointKeyHash> index;
  index.reserve(cloud.size());
  for (std::size_t i = 0; i < cloud.size(); ++i)
  {
    index.emplace(keyOf(cloud.points[i]), i);
  }
  return index;
}

/// Whether every point of the cloud has finite coordinates.
inline bool allFinite(const Cloud& cloud)
{
  for (const Point& p : cloud.points)
  {
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
    {
      return false;
    }
  }
  return true;
}

/// Whether the rings of a cloud never decrease along it.
inline bool ringOrdered(const Cloud& cloud)
{
  for (std::size_t i = 1; i < cloud.size(); ++i)
  {
    if (cloud.points[i].ring < cloud.points[i - 1].ring)
    {
      return false;
    }
  }
  return true;
}

/// The central difference of `residuals()` by one of the parameters it reads, `coordinate` (restored
/// afterwards): the numeric column that an analytic Jacobian is checked against.
inline Eigen::VectorXd centralDifference(const std::function<Eigen::VectorXd()>& residuals, double& coordinate,
                                         double step = 1e-6)
{
  const double kept = coordinate;
  coordinate = kept + step;
  const Eigen::VectorXd plus = residuals();
  coordinate = kept - step;
  const Eigen::VectorXd minus = residuals();
  coordinate = kept;
  return (plus - minus) / (2.0 * step);
}

}  // namespace test_support
}  // namespace aloam
