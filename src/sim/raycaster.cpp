#include "aloam_nodelet/sim/raycaster.h"

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace aloam
{
namespace sim
{
namespace
{
constexpr double kDegToRad = M_PI / 180.0;
constexpr double kTwoPi = 2.0 * M_PI;

// Independent random streams per ray.
constexpr std::uint64_t kNoiseStream = 1;
constexpr std::uint64_t kDropoutStream = 2;
constexpr std::uint64_t kGoldenGamma = 0x9E3779B97F4A7C15ull;

// SplitMix64 finalizer: a well-mixed 64-bit hash.
std::uint64_t mix64(std::uint64_t z)
{
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

// Counter-based random numbers: a pure function of (seed, ray, stream, draw), so the result does
// not depend on the order in which rays are cast.
class RayRandom
{
public:
  RayRandom(unsigned seed, std::uint64_t ray_index, std::uint64_t stream)
    : key_(mix64(mix64(static_cast<std::uint64_t>(seed) + kGoldenGamma) ^ (ray_index * kGoldenGamma + stream)))
  {
  }

  // Uniform in [0, 1) with 53 random bits.
  double uniform01()
  {
    constexpr double kTwoToMinus53 = 1.0 / 9007199254740992.0;
    key_ += kGoldenGamma;
    return static_cast<double>(mix64(key_) >> 11) * kTwoToMinus53;
  }
  // Standard normal (Box-Muller).
  double gaussian()
  {
    const double u1 = 1.0 - uniform01();  // (0, 1]
    const double u2 = uniform01();
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(kTwoPi * u2);
  }

private:
  std::uint64_t key_;
};
}  // namespace

Cloud scan(const Scene& scene, const SensorModel& model, const PoseFunction& sensor_pose_at, const ScanOptions& options,
           std::vector<int>* surface_ids)
{
  const int rings = model.numRings();
  const int columns = model.columns();
  const double period = model.scanPeriod();

  // Beam directions in the sensor frame: elevation per ring, azimuth per column.
  std::vector<double> cos_elevation(static_cast<std::size_t>(rings));
  std::vector<double> sin_elevation(static_cast<std::size_t>(rings));
  for (int r = 0; r < rings; ++r)
  {
    const double e = model.elevationsDeg()[static_cast<std::size_t>(r)] * kDegToRad;
    cos_elevation[static_cast<std::size_t>(r)] = std::cos(e);
    sin_elevation[static_cast<std::size_t>(r)] = std::sin(e);
  }

  const std::size_t num_rays = static_cast<std::size_t>(rings) * static_cast<std::size_t>(columns);
  Cloud cloud;
  cloud.reserve(num_rays);
  if (surface_ids != nullptr)
  {
    surface_ids->clear();
    surface_ids->reserve(num_rays);
  }

  for (int c = 0; c < columns; ++c)
  {
    const double fraction = static_cast<double>(c) / columns;
    const double t = fraction * period;
    const double azimuth = options.start_azimuth_rad - kTwoPi * fraction;
    const double cos_az = std::cos(azimuth);
    const double sin_az = std::sin(azimuth);
    const Eigen::Isometry3d pose = sensor_pose_at(t);
    const Eigen::Matrix3d rotation = pose.linear();
    const Eigen::Vector3d origin = pose.translation();

    for (int r = 0; r < rings; ++r)
    {
      const std::size_t ri = static_cast<std::size_t>(r);
      const Eigen::Vector3d dir_sensor(cos_elevation[ri] * cos_az, cos_elevation[ri] * sin_az, sin_elevation[ri]);
      const Eigen::Vector3d dir_world = rotation * dir_sensor;
      const std::optional<Hit> hit = scene.intersect(origin, dir_world, options.max_range);
      if (!hit)
      {
        continue;
      }
      const std::uint64_t ray_index =
          static_cast<std::uint64_t>(c) * static_cast<std::uint64_t>(rings) + static_cast<std::uint64_t>(r);
      if (options.dropout_probability > 0.0 &&
          RayRandom(options.seed, ray_index, kDropoutStream).uniform01() < options.dropout_probability)
      {
        continue;
      }
      double range = hit->distance;
      if (options.range_noise_sigma > 0.0)
      {
        range += options.range_noise_sigma * RayRandom(options.seed, ray_index, kNoiseStream).gaussian();
      }
      if (range < options.min_range || range > options.max_range)
      {
        continue;
      }

      const double cos_incidence = std::abs(hit->normal.dot(dir_world.normalized()));
      const double reflectivity = scene.primitive(hit->surface_id).reflectivity;
      const Eigen::Vector3d p = range * dir_sensor;
      Point point;
      point.x = static_cast<float>(p.x());
      point.y = static_cast<float>(p.y());
      point.z = static_cast<float>(p.z());
      point.intensity =
          static_cast<float>(std::clamp(kMaxIntensity * reflectivity * cos_incidence, 0.0, kMaxIntensity));
      point.time = static_cast<float>(t);
      point.ring = static_cast<std::uint16_t>(r);
      cloud.push_back(point);
      if (surface_ids != nullptr)
      {
        surface_ids->push_back(hit->surface_id);
      }
    }
  }
  cloud.width = static_cast<std::uint32_t>(cloud.size());
  cloud.height = 1;
  cloud.is_dense = true;
  return cloud;
}

Cloud scanStatic(const Scene& scene, const SensorModel& model, const Eigen::Isometry3d& pose,
                 const ScanOptions& options, std::vector<int>* surface_ids)
{
  return scan(
      scene, model, [&pose](double) { return pose; }, options, surface_ids);
}

}  // namespace sim
}  // namespace aloam
