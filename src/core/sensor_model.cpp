#include "aloam_nodelet/core/sensor_model.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace aloam
{
namespace
{
constexpr double kRadToDeg = 180.0 / M_PI;
constexpr double kDegToRad = M_PI / 180.0;

std::vector<double> linspace(int n, double lo, double hi)
{
  std::vector<double> v(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i)
  {
    v[static_cast<std::size_t>(i)] = n == 1 ? lo : lo + (hi - lo) * i / (n - 1);
  }
  return v;
}

// HDL-64E S2: an upper block of 32 beams at 1/3 deg spacing from +2 deg down and a lower block of
// 32 beams at 1/2 deg spacing from -8.83 deg down (the layout A-LOAM's ring formula assumes).
std::vector<double> hdl64Table()
{
  std::vector<double> v;
  for (int k = 0; k < 32; ++k)
  {
    v.push_back(2.0 - k / 3.0);
    v.push_back(-8.83 - 0.5 * k);
  }
  return v;
}

// VLP-32C beam elevations from the sensor's user manual (non-uniform, dense near the horizon).
std::vector<double> vlp32cTable()
{
  return { -25.0, -15.639, -11.31, -8.843, -7.254, -6.148, -5.333, -4.667, -4.0,   -3.667, -3.333,
           -3.0,  -2.667,  -2.333, -2.0,   -1.667, -1.333, -1.0,   -0.667, -0.333, 0.0,    0.333,
           0.667, 1.0,     1.333,  1.667,  2.333,  3.333,  4.667,  7.0,    10.333, 15.0 };
}
}  // namespace

std::vector<std::string> SensorModel::presetNames()
{
  return { "VLP16", "HDL32", "HDL64", "VLP32C", "OS1_64", "OS0_64", "OS1_128" };
}

std::optional<SensorModel> SensorModel::fromPreset(const std::string& name)
{
  SensorModel m;
  if (name == "VLP16")
  {
    m = uniform(16, -15.0, 15.0);
    m.columns_ = 1800;
  }
  else if (name == "HDL32")
  {
    m = uniform(32, -30.67, 10.67);
    m.columns_ = 2170;
  }
  else if (name == "HDL64")
  {
    m = fromTable(hdl64Table());
    m.columns_ = 2083;
  }
  else if (name == "VLP32C")
  {
    m = fromTable(vlp32cTable());
    m.columns_ = 1800;
  }
  else if (name == "OS1_64")
  {
    m = uniform(64, -22.5, 22.5);
    m.columns_ = 1024;
    m.ring_field_from_top_ = true;
  }
  else if (name == "OS0_64")
  {
    m = uniform(64, -45.0, 45.0);
    m.columns_ = 1024;
    m.ring_field_from_top_ = true;
  }
  else if (name == "OS1_128")
  {
    m = uniform(128, -22.5, 22.5);
    m.columns_ = 1024;
    m.ring_field_from_top_ = true;
  }
  else
  {
    return std::nullopt;
  }
  m.name_ = name;
  return m;
}

SensorModel SensorModel::uniform(int beams, double min_elevation_deg, double max_elevation_deg)
{
  if (beams < 1)
  {
    throw std::invalid_argument("SensorModel::uniform needs at least one beam");
  }
  return fromTable(
      linspace(beams, std::min(min_elevation_deg, max_elevation_deg), std::max(min_elevation_deg, max_elevation_deg)));
}

SensorModel SensorModel::fromTable(std::vector<double> elevations_deg)
{
  elevations_deg.erase(
      std::remove_if(elevations_deg.begin(), elevations_deg.end(), [](double e) { return !std::isfinite(e); }),
      elevations_deg.end());
  if (elevations_deg.empty())
  {
    throw std::invalid_argument("SensorModel::fromTable needs at least one finite elevation");
  }
  SensorModel m;
  std::sort(elevations_deg.begin(), elevations_deg.end());
  m.elevations_deg_ = std::move(elevations_deg);
  m.finalize();
  return m;
}

void SensorModel::finalize()
{
  const auto& e = elevations_deg_;
  const std::size_t n = e.size();
  // A single beam accepts +-1 deg; otherwise the outer beams accept half their neighbour spacing.
  const double outer_low = n > 1 ? 0.5 * (e[1] - e[0]) : 1.0;
  const double outer_high = n > 1 ? 0.5 * (e[n - 1] - e[n - 2]) : 1.0;
  lowest_bound_deg_ = e.front() - outer_low;
  upper_bounds_deg_.resize(n);
  for (std::size_t i = 0; i + 1 < n; ++i)
  {
    upper_bounds_deg_[i] = 0.5 * (e[i] + e[i + 1]);
  }
  upper_bounds_deg_[n - 1] = e[n - 1] + outer_high;
  // tan is increasing on (-90, 90) deg, so slopes compare as elevations do.
  const auto slope = [](double deg)
  {
    if (deg >= 90.0)
    {
      return std::numeric_limits<double>::infinity();
    }
    if (deg <= -90.0)
    {
      return -std::numeric_limits<double>::infinity();
    }
    return std::tan(deg * kDegToRad);
  };
  lowest_bound_slope_ = slope(lowest_bound_deg_);
  upper_bounds_slope_.resize(n);
  for (std::size_t i = 0; i < n; ++i)
  {
    upper_bounds_slope_[i] = slope(upper_bounds_deg_[i]);
  }
}

int SensorModel::ringForElevation(double elevation_rad) const
{
  const double deg = elevation_rad * kRadToDeg;
  if (!std::isfinite(deg) || deg < lowest_bound_deg_ || deg > upper_bounds_deg_.back())
  {
    return -1;
  }
  const auto it = std::lower_bound(upper_bounds_deg_.begin(), upper_bounds_deg_.end(), deg);
  return static_cast<int>(it - upper_bounds_deg_.begin());
}

int SensorModel::ringForPoint(double x, double y, double z) const
{
  const double slope = z / std::sqrt(x * x + y * y);  // +-inf straight up or down, NaN at the origin
  if (!(slope >= lowest_bound_slope_ && slope <= upper_bounds_slope_.back()))
  {
    return -1;
  }
  const auto it = std::lower_bound(upper_bounds_slope_.begin(), upper_bounds_slope_.end(), slope);
  return static_cast<int>(it - upper_bounds_slope_.begin());
}

int SensorModel::ringFromField(int field_ring) const
{
  if (!ring_field_from_top_)
  {
    return field_ring;
  }
  return field_ring >= 0 && field_ring < numRings() ? numRings() - 1 - field_ring : -1;
}

}  // namespace aloam
