// Tests of sim::LongDrive, the endless street of the long-run check and benchmarks: deterministic for a
// seed, new territory all along, a scene that stays small however far the drive goes.
#include <cmath>

#include <gtest/gtest.h>

#include "aloam_nodelet/sim/long_drive.h"

namespace aloam
{
namespace
{
constexpr long kFarSweep = 30000;  // 50 minutes, 30 km at 10 m/s
// A VLP-16 sweep in the street hits the ground, the facades and the parked cars: measured 27,000 points.
constexpr std::size_t kMinPointsPerSweep = 15000;

SensorModel vlp16()
{
  return *SensorModel::fromPreset("VLP16");
}

TEST(LongDriveTest, SameSeedSameSweepsOtherSeedOtherStreet)
{
  sim::LongDriveOptions options;
  options.seed = 5;
  sim::LongDrive a(options), b(options);
  const Cloud ca = a.sweep(42, vlp16());
  const Cloud cb = b.sweep(42, vlp16());
  ASSERT_EQ(ca.size(), cb.size());
  for (std::size_t i = 0; i < ca.size(); i += 101)
  {
    EXPECT_EQ(ca.points[i].x, cb.points[i].x);
    EXPECT_EQ(ca.points[i].ring, cb.points[i].ring);
  }
  options.seed = 6;
  sim::LongDrive c(options);
  const Cloud cc = c.sweep(42, vlp16());
  std::size_t differing = 0;
  for (std::size_t i = 0; i < std::min(ca.size(), cc.size()); ++i)
  {
    differing += std::fabs(ca.points[i].x - cc.points[i].x) > 0.01f ? 1 : 0;
  }
  EXPECT_GT(differing, ca.size() / 10);
}

TEST(LongDriveTest, TrajectoryDrivesOnAtTheGivenSpeed)
{
  sim::LongDriveOptions options;
  options.speed = 12.0;
  sim::LongDrive drive(options);
  EXPECT_DOUBLE_EQ(drive.sweepStamp(9), 1.0);
  const Eigen::Vector3d start = drive.sweepEndPose(0).translation();
  const Eigen::Vector3d far = drive.sweepEndPose(kFarSweep).translation();
  EXPECT_NEAR(far.x() - start.x(), options.speed * options.scan_period * kFarSweep, 1e-6);
  EXPECT_LE(std::fabs(far.y()), options.weave_amplitude_m + 1e-9);
  EXPECT_NEAR(far.z(), options.height_m, 1e-9);
  EXPECT_TRUE(drive.sweepEndPose(7).isApprox(drive.poseAt(0.8)));
}

TEST(LongDriveTest, NewTerritoryAllAlongAndABoundedScene)
{
  sim::LongDrive drive;
  const SensorModel sensor = vlp16();
  std::size_t most_primitives = 0, fewest_primitives = static_cast<std::size_t>(-1);
  std::size_t places = 0;
  for (long k = 0; k <= kFarSweep; k += kFarSweep / 12, ++places)
  {
    const Cloud cloud = drive.sweep(k, sensor);
    EXPECT_GE(cloud.size(), kMinPointsPerSweep) << "sweep " << k;
    // Nothing in the way: the sensor is on the road, not inside a building or a car.
    std::size_t close = 0;
    for (const Point& p : cloud.points)
    {
      close += std::hypot(p.x, p.y) < 2.0 && p.z > -1.0 ? 1 : 0;
    }
    EXPECT_LT(close, cloud.size() / 100) << "sweep " << k;
    most_primitives = std::max(most_primitives, drive.scenePrimitives());
    fewest_primitives = std::min(fewest_primitives, drive.scenePrimitives());
  }
  // Every place (2.5 km apart) has tiles of its own, generated on the way; those behind are forgotten: the
  // scene does not grow.
  EXPECT_GE(drive.tilesGenerated(), 2 * places);
  EXPECT_LE(most_primitives, 3 * fewest_primitives);
}

TEST(LongDriveTest, ColumnStepThinsTheSweep)
{
  sim::LongDriveOptions options;
  sim::LongDrive full(options);
  options.column_step = 2;
  sim::LongDrive thin(options);
  const std::size_t all = full.sweep(100, vlp16()).size();
  const std::size_t half = thin.sweep(100, vlp16()).size();
  EXPECT_NEAR(static_cast<double>(half) / static_cast<double>(all), 0.5, 0.05);
}

}  // namespace
}  // namespace aloam
