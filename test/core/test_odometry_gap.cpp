// Tests of LaserOdometry::resetMotionPrior, what the odometry nodelet calls after a gap in the stamps: the
// sweep after the gap starts from an identity prior, is not deskewed with the motion across the gap, and
// that motion is not the prior of the sweep after it.
#include <cstdint>
#include <memory>

#include <gtest/gtest.h>

#include "aloam_nodelet/core/laser_odometry.h"
#include "aloam_nodelet/core/scan_registration.h"
#include "test_support.h"

namespace aloam
{
namespace
{
namespace ts = test_support;

constexpr double kStartX = 60.0;
constexpr double kSpeedBefore = 5.0;  // m/s before the gap
constexpr double kSpeedAfter = 2.0;   // m/s after it
constexpr int kSweepsBefore = 3;
constexpr double kGapStart = kSweepsBefore * 0.1;  // s, end of the last sweep before the gap
constexpr double kGapEnd = 2.3;                    // s, start of the first sweep after it
constexpr double kAcrossGap = 0.8;                 // m from the last sweep end before the gap to the first after it
constexpr double kExact = 1e-9;
// m: the sweep after the gap cannot be deskewed (its velocity is unknown), so its own motion (kSpeedAfter *
// 0.1 s) biases the solved motion by about half of it (measured 0.11 m), plus solver slack.
constexpr double kSolvedWithin = 0.2;

// Sensor x on the street at time t: kSpeedBefore until the gap; after it the car goes on at kSpeedAfter,
// placed so that the first sweep after the gap ends kAcrossGap beyond the last one before it.
double xAt(double t)
{
  if (t <= kGapStart + 1e-9)
  {
    return kStartX + kSpeedBefore * t;
  }
  const double first_end = kStartX + kSpeedBefore * kGapStart + kAcrossGap;
  return first_end + kSpeedAfter * (t - (kGapEnd + 0.1));
}

// Sweep over [start, start + 0.1 s] with real motion distortion, stamped at its end.
std::shared_ptr<const FeatureSet> sweepFrom(const SensorModel& sensor, double start)
{
  const Cloud cloud = ts::movingSweep(sensor, [&](double t) { return ts::streetPose(xAt(start + t)); });
  ScanRegistrationConfig config;
  config.sensor = sensor;
  ScanRegistration registration(config);
  auto f = std::make_shared<FeatureSet>();
  EXPECT_TRUE(registration.process(cloud, start + 0.1, true, true, *f));
  return f;
}

// Too few points to match anything: odometry keeps its prior, which makes the prior observable.
std::shared_ptr<const FeatureSet> sparseSweep(double stamp)
{
  auto sparse = std::make_shared<FeatureSet>();
  sparse->stamp = stamp;
  for (int i = 0; i < 3; ++i)
  {
    const Point p = ts::makePoint(5.0 + i, 2.0 * i, 0.5, static_cast<std::uint16_t>(4 + i));
    sparse->sharp.push_back(p);
    sparse->less_sharp.push_back(p);
    sparse->flat.push_back(p);
    sparse->less_flat.push_back(p);
    sparse->full.push_back(p);
  }
  return sparse;
}

LaserOdometry deskewingOdometry()
{
  LaserOdometryConfig config;
  config.deskew = true;
  config.max_iterations = 8;  // converges from an identity prior (see test_laser_odometry.cpp)
  config.outer_iterations = 3;
  return LaserOdometry(config);
}

// Sweeps before the gap; returns the last frame.
OdometryFrame driveToGap(const SensorModel& sensor, LaserOdometry& odometry)
{
  OdometryFrame frame;
  for (int k = 0; k < kSweepsBefore; ++k)
  {
    frame = odometry.process(sweepFrom(sensor, 0.1 * k));
  }
  EXPECT_EQ(frame.status, OdometryStatus::kOk);
  return frame;
}

TEST(OdometryGapTest, ResetPriorMeansNoExtrapolation)
{
  const SensorModel sensor = ts::preset("VLP16");
  LaserOdometry odometry = deskewingOdometry();
  const OdometryFrame moving = driveToGap(sensor, odometry);
  ASSERT_GT(moving.motion.t.norm(), 0.5 * kSpeedBefore * 0.1);

  odometry.resetMotionPrior();
  const OdometryFrame degraded = odometry.process(sparseSweep(kGapEnd + 0.1));
  EXPECT_EQ(degraded.status, OdometryStatus::kDegraded);
  // With the prior kept it would have moved on by the last motion; reset, it stays where it was.
  EXPECT_NEAR((degraded.pose.t - moving.pose.t).norm(), 0.0, kExact);
  EXPECT_NEAR(degraded.motion.t.norm(), 0.0, kExact);
  EXPECT_TRUE(degraded.pose.isFinite());
}

TEST(OdometryGapTest, SweepAfterGapIsSolvedButNeitherDeskewedNorAPrior)
{
  const SensorModel sensor = ts::preset("VLP16");
  LaserOdometry odometry = deskewingOdometry();
  const OdometryFrame before = driveToGap(sensor, odometry);
  EXPECT_FALSE(before.distorted);

  odometry.resetMotionPrior();
  const auto after_gap = sweepFrom(sensor, kGapEnd);
  const OdometryFrame gap = odometry.process(after_gap);
  ASSERT_EQ(gap.status, OdometryStatus::kOk);
  // The motion across the gap is found from the identity prior...
  EXPECT_NEAR(gap.motion.t.x(), kAcrossGap, kSolvedWithin);
  EXPECT_NEAR((gap.pose.t - before.pose.t).norm(), kAcrossGap, kSolvedWithin);
  // ... but the clouds handed on are not deskewed with it (it did not happen during the sweep).
  EXPECT_TRUE(gap.distorted);
  ASSERT_EQ(gap.full->size(), after_gap->full.size());
  for (std::size_t i = 0; i < gap.full->size(); i += 97)
  {
    EXPECT_NEAR(gap.full->points[i].x, after_gap->full.points[i].x, 1e-4);
    EXPECT_NEAR(gap.full->points[i].y, after_gap->full.points[i].y, 1e-4);
  }

  // Nor is it the prior of the next sweep.
  const OdometryFrame next = odometry.process(sparseSweep(kGapEnd + 0.2));
  EXPECT_EQ(next.status, OdometryStatus::kDegraded);
  EXPECT_NEAR((next.pose.t - gap.pose.t).norm(), 0.0, kExact);
}

TEST(OdometryGapTest, DriveGoesOnAfterTheGap)
{
  const SensorModel sensor = ts::preset("VLP16");
  LaserOdometry odometry = deskewingOdometry();
  driveToGap(sensor, odometry);
  odometry.resetMotionPrior();
  OdometryFrame last;
  double end = 0.0;
  for (int k = 0; k < 5; ++k)
  {
    const double start = kGapEnd + 0.1 * k;
    last = odometry.process(sweepFrom(sensor, start));
    end = start + 0.1;
    EXPECT_EQ(last.status, OdometryStatus::kOk) << "sweep " << k << " after the gap";
  }
  // The odometry starts at identity at the end of the first sweep.
  EXPECT_NEAR(last.pose.t.x(), xAt(end) - xAt(0.1), kSolvedWithin);
  EXPECT_NEAR(last.pose.t.y(), 0.0, kSolvedWithin);
}

}  // namespace
}  // namespace aloam
