// Beam layout of a spinning lidar: which ring a return belongs to, from its elevation.
#pragma once

#include <optional>
#include <string>
#include <vector>

namespace aloam
{
/// Per-beam elevation table of a spinning lidar. Ring i is the i-th beam counted from the lowest
/// elevation upwards (the velodyne_pointcloud convention).
class SensorModel
{
public:
  /// Known presets: VLP16, HDL32, HDL64, VLP32C, OS1_64, OS0_64, OS1_128. Case-sensitive; empty if unknown.
  static std::optional<SensorModel> fromPreset(const std::string& name);
  static std::vector<std::string> presetNames();
  /// `beams` uniformly spaced beams from `min_elevation_deg` to `max_elevation_deg` (inclusive).
  static SensorModel uniform(int beams, double min_elevation_deg, double max_elevation_deg);
  /// Arbitrary table, in degrees, any order (it is sorted). At least one beam.
  static SensorModel fromTable(std::vector<double> elevations_deg);

  const std::string& name() const { return name_; }
  int numRings() const { return static_cast<int>(elevations_deg_.size()); }
  /// Ascending beam elevations in degrees; index = ring.
  const std::vector<double>& elevationsDeg() const { return elevations_deg_; }
  /// Nominal points per ring and sweep (azimuth steps); used by the simulator and for sizing.
  int columns() const { return columns_; }
  /// Nominal sweep period in seconds.
  double scanPeriod() const { return scan_period_; }
  /// True when the driver's `ring` field counts beams from the top: ouster_ros publishes the image row,
  /// row 0 being the highest beam. Velodyne drivers count from the lowest beam, as this model does.
  bool ringFieldFromTop() const { return ring_field_from_top_; }
  /// This model's ring (0 = lowest beam) of a driver's `ring` value; -1 when a top-down value lies
  /// outside the table. Bottom-up values pass through unchanged.
  int ringFromField(int field_ring) const;

  /// Ring of the nearest beam, or -1 when the elevation lies outside the table by more than half the
  /// spacing of the outermost beams.
  int ringForElevation(double elevation_rad) const;
  /// ringForElevation of the point (x, y, z) seen from the sensor, without an arctangent: the slope
  /// z / hypot(x, y) against the tangents of the ring bounds (the same rings, at a fraction of the cost).
  int ringForPoint(double x, double y, double z) const;

private:
  std::string name_ = "custom";
  std::vector<double> elevations_deg_;
  std::vector<double> upper_bounds_deg_;  // ring i takes elevations up to upper_bounds_deg_[i]
  double lowest_bound_deg_ = 0.0;
  std::vector<double> upper_bounds_slope_;  // tan of upper_bounds_deg_ (+-inf beyond +-90 deg)
  double lowest_bound_slope_ = 0.0;
  int columns_ = 1800;
  double scan_period_ = 0.1;
  bool ring_field_from_top_ = false;

  void finalize();
};

}  // namespace aloam
