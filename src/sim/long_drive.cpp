#include "aloam_nodelet/sim/long_drive.h"

#include <cmath>
#include <type_traits>
#include <variant>

namespace aloam
{
namespace sim
{
namespace
{
// Half width of the ground of a window of tiles (m): beyond the lidar's range from the street.
constexpr double kGroundHalfWidth = 250.0;

// `shape` moved by `offset` along x. The street's ground (the only plane patch) is not moved: each window
// has a ground of its own.
std::optional<Shape> shiftedAlongX(const Shape& shape, double offset)
{
  return std::visit(
      [offset](const auto& s) -> std::optional<Shape>
      {
        using T = std::decay_t<decltype(s)>;
        const Eigen::Vector3d dx(offset, 0.0, 0.0);
        if constexpr (std::is_same_v<T, OrientedBox>)
        {
          return OrientedBox(s.center() + dx, s.halfExtents(), s.yaw());
        }
        else if constexpr (std::is_same_v<T, VerticalCylinder>)
        {
          return VerticalCylinder(s.centerX() + offset, s.centerY(), s.radius(), s.zMin(), s.zMax());
        }
        else if constexpr (std::is_same_v<T, Sphere>)
        {
          return Sphere(s.center() + dx, s.radius());
        }
        else
        {
          return std::nullopt;
        }
      },
      shape);
}

// A seed per tile, different for neighbouring tiles and drives (odd multipliers of a hash mix).
unsigned tileSeed(unsigned seed, long index)
{
  return seed * 2654435761u + static_cast<unsigned>(index) * 40503u + 1u;
}
}  // namespace

LongDrive::LongDrive(const LongDriveOptions& options) : options_(options)
{
  CarDriveOptions car;
  car.speed = options.speed;
  car.start_x = 0.0;
  car.height_m = options.height_m;
  car.weave_amplitude_m = options.weave_amplitude_m;
  car.weave_period_s = options.weave_period_s;
  pose_at_ = carDrive(car);
}

std::vector<Primitive> LongDrive::tile(long index)
{
  // A street of one tile's length; what lies on it (buildings, cars, poles, trees) is kept, what the
  // generator adds beyond its ends is left to the neighbouring tiles.
  const double length = options_.tile_length_m;
  const Scene street = Scene::urbanStreet(tileSeed(options_.seed, index), length);
  const double offset = static_cast<double>(index) * length;
  std::vector<Primitive> out;
  for (const Primitive& p : street.primitives())
  {
    const Aabb box = shapeBounds(p.shape);
    const double centre_x = 0.5 * (box.min.x() + box.max.x());
    if (centre_x < 0.0 || centre_x >= length)
    {
      continue;
    }
    if (const std::optional<Shape> shifted = shiftedAlongX(p.shape, offset))
    {
      out.emplace_back(*shifted, p.surface_class, p.reflectivity);
    }
  }
  ++tiles_generated_;
  return out;
}

const Scene& LongDrive::sceneForSweep(long k)
{
  const double x_begin = poseAt(static_cast<double>(k) * options_.scan_period).translation().x();
  const double x_end = sweepEndPose(k).translation().x();
  const double length = options_.tile_length_m;
  const long first = static_cast<long>(std::floor((std::min(x_begin, x_end) - options_.reach_m) / length));
  const long last = static_cast<long>(std::floor((std::max(x_begin, x_end) + options_.reach_m) / length));
  if (scene_ && first == first_tile_ && last == last_tile_)
  {
    return *scene_;
  }
  // Keep the tiles still in the window, generate the new ones, rebuild the scene from them.
  for (auto it = tiles_.begin(); it != tiles_.end();)
  {
    it = (it->first < first || it->first > last) ? tiles_.erase(it) : std::next(it);
  }
  auto scene = std::make_unique<Scene>();
  const double ground_begin = static_cast<double>(first) * length - kGroundHalfWidth;
  const double ground_end = static_cast<double>(last + 1) * length + kGroundHalfWidth;
  scene->add(PlanePatch::horizontal(0.0, ground_begin, ground_end, -kGroundHalfWidth, kGroundHalfWidth),
             SurfaceClass::Ground);
  for (long index = first; index <= last; ++index)
  {
    auto found = tiles_.find(index);
    if (found == tiles_.end())
    {
      found = tiles_.emplace(index, tile(index)).first;
    }
    for (const Primitive& p : found->second)
    {
      scene->add(p);
    }
  }
  scene_ = std::move(scene);
  first_tile_ = first;
  last_tile_ = last;
  return *scene_;
}

Cloud LongDrive::sweep(long k, const SensorModel& sensor)
{
  const Scene& scene = sceneForSweep(k);
  ScanOptions scan;
  scan.range_noise_sigma = options_.range_noise_sigma;
  scan.seed = tileSeed(options_.seed, k);
  const double start = static_cast<double>(k) * options_.scan_period;
  Cloud cloud = aloam::sim::scan(
      scene, sensor, [&](double t) { return poseAt(start + t); }, scan);
  if (options_.column_step > 1)
  {
    // Column c fired at c / columns of the sweep (see aloam::sim::scan).
    const double columns_per_second = sensor.columns() / sensor.scanPeriod();
    Cloud kept;
    kept.points.reserve(cloud.size() / static_cast<std::size_t>(options_.column_step) + 1);
    for (const Point& p : cloud.points)
    {
      if (std::lround(p.time * columns_per_second) % options_.column_step == 0)
      {
        kept.points.push_back(p);
      }
    }
    setUnorganized(kept);
    cloud = std::move(kept);
  }
  return cloud;
}

}  // namespace sim
}  // namespace aloam
