// Tests of MappingSession (the mapping nodelet's core) and of the time policy the stages and the Pipeline share.
#include <cstdint>
#include <memory>
#include <vector>

#include <gtest/gtest.h>

#include "aloam_nodelet/core/latest_slot.h"
#include "aloam_nodelet/core/mapping_session.h"
#include "aloam_nodelet/core/pipeline.h"
#include "aloam_nodelet/core/rep105.h"
#include "test_support.h"

namespace aloam
{
namespace
{
namespace ts = test_support;

constexpr int kSweeps = 8;
constexpr double kStep = 1.0;  // metres between sweeps (static sweeps, no distortion)

std::int64_t nanoseconds(double seconds)
{
  return static_cast<std::int64_t>(seconds * 1e9 + 0.5);
}

// Odometry frames of a short straight drive (registration + odometry), made once.
const std::vector<OdometryFrame>& driveFrames()
{
  static const std::vector<OdometryFrame> frames = []
  {
    const SensorModel sensor = ts::preset("VLP16");
    ScanRegistrationConfig registration_config;
    registration_config.sensor = sensor;
    ScanRegistration registration(registration_config);
    LaserOdometry odometry;
    std::vector<OdometryFrame> out;
    for (int k = 0; k < kSweeps; ++k)
    {
      const Cloud cloud = ts::staticSweep(sensor, ts::streetPose(20.0 + kStep * k));
      auto features = std::make_shared<FeatureSet>();
      const double stamp = 0.1 * (k + 1);
      EXPECT_TRUE(registration.process(cloud, stamp, true, true, *features));
      out.push_back(odometry.track(features));
      odometry.indexLast();
    }
    return out;
  }();
  return frames;
}

double stampOf(int k)
{
  return 0.1 * (k + 1);
}

// The session registers as LaserMapping does (registerFrame + updateMap), whichever thread calls.
TEST(MappingSessionTest, RegistersLikeLaserMapping)
{
  MappingSession session;
  LaserMapping direct;
  for (int k = 0; k < kSweeps; ++k)
  {
    const OdometryFrame& frame = driveFrames()[static_cast<std::size_t>(k)];
    const Admission admission = session.admit(frame, nanoseconds(stampOf(k)));
    ASSERT_TRUE(admission.taken);
    EXPECT_TRUE(ts::translationError(admission.corrected, direct.correct(frame.pose)) < 1e-12) << k;
    const MappingResult mine = session.registerFrame(frame);
    session.updateMap();
    const MappingResult theirs = direct.process(frame);
    EXPECT_LT(ts::translationError(mine.pose, theirs.pose), 1e-12) << k;
  }
  const MappingSessionStats stats = session.stats();
  EXPECT_EQ(stats.frames_registered, static_cast<std::size_t>(kSweeps));
  EXPECT_EQ(stats.frames_mapped, static_cast<std::size_t>(kSweeps));
  const std::size_t points = session.withMap([](const CubeMap& map) { return map.cornerCount() + map.surfCount(); });
  EXPECT_EQ(points, direct.map().cornerCount() + direct.map().surfCount());
  // Moving 1 m per sweep, the mapped poses end near 7 m from the first.
  const RecordedTrajectory trajectory = session.trajectory();
  ASSERT_EQ(trajectory.poses.size(), static_cast<std::size_t>(kSweeps));
  const std::vector<Pose> relative = trajectory.relativeToFirst();
  EXPECT_LT(relative.front().t.norm(), 1e-12);
  EXPECT_NEAR(relative.back().t.x(), kStep * (kSweeps - 1), 0.1);
}

// A frame registered but not yet added to the map is added before the next registration.
TEST(MappingSessionTest, PendingUpdateIsAddedBeforeTheNextFrame)
{
  MappingSession lazy, eager;
  for (int k = 0; k < 3; ++k)
  {
    const OdometryFrame& frame = driveFrames()[static_cast<std::size_t>(k)];
    lazy.admit(frame, nanoseconds(stampOf(k)));
    eager.admit(frame, nanoseconds(stampOf(k)));
    const MappingResult a = lazy.registerFrame(frame);  // never updated explicitly
    const MappingResult b = eager.registerFrame(frame);
    EXPECT_TRUE(eager.updateMap());
    EXPECT_FALSE(eager.updateMap());  // nothing pending twice
    EXPECT_LT(ts::translationError(a.pose, b.pose), 1e-12) << k;
  }
  OdometryFrame added;
  MappingResult result;
  EXPECT_TRUE(lazy.updateMap(&added, &result));
  EXPECT_DOUBLE_EQ(added.stamp, driveFrames()[2].stamp);
  EXPECT_GT(result.map_surfs, 0u);
}

// Duplicates and late frames are dropped; a jump back and an odometry restart start a new map.
TEST(MappingSessionTest, TimePolicyAndResets)
{
  MappingSession session;
  for (int k = 0; k < 4; ++k)
  {
    const OdometryFrame& frame = driveFrames()[static_cast<std::size_t>(k)];
    ASSERT_TRUE(session.admit(frame, nanoseconds(stampOf(k))).taken);
    session.registerFrame(frame);
  }
  const OdometryFrame& next = driveFrames()[4];
  EXPECT_FALSE(session.admit(next, nanoseconds(stampOf(3))).taken);         // duplicate
  EXPECT_FALSE(session.admit(next, nanoseconds(stampOf(3) - 0.05)).taken);  // late
  const Admission back = session.admit(driveFrames()[0], nanoseconds(stampOf(3) - 5.0));
  ASSERT_TRUE(back.taken);
  EXPECT_EQ(back.reset, ResetReason::kJumpedBack);
  EXPECT_LT(ts::translationError(back.corrected, driveFrames()[0].pose), 1e-12);  // no old correction
  session.registerFrame(driveFrames()[0]);
  EXPECT_EQ(session.stats().frames_in_map, 1u);
  EXPECT_EQ(session.trajectory().poses.size(), 1u);

  // Odometry restarting at identity (status kInitialized) while the stamps go on.
  const Admission restart = session.admit(driveFrames()[0], nanoseconds(100.0));
  EXPECT_EQ(restart.reset, ResetReason::kOdometryRestarted);
  session.registerFrame(driveFrames()[0]);
  EXPECT_EQ(session.stats().odometry_restarts, 1u);
  EXPECT_EQ(session.stats().frames_in_map, 1u);
  const MappingSessionStats stats = session.stats();
  EXPECT_EQ(stats.stamps.duplicates, 1u);
  EXPECT_EQ(stats.stamps.out_of_order, 1u);
  EXPECT_EQ(stats.stamps.jumps_back, 1u);

  session.requestReset();
  session.registerFrame(driveFrames()[1]);
  EXPECT_EQ(session.stats().frames_in_map, 1u);
}

TEST(MappingSessionTest, TrajectoryIsBounded)
{
  MappingSessionConfig config;
  config.trajectory_max_poses = 4;
  MappingSession session(config);
  for (int k = 0; k < kSweeps; ++k)
  {
    session.admit(driveFrames()[static_cast<std::size_t>(k)], nanoseconds(stampOf(k)));
    session.registerFrame(driveFrames()[static_cast<std::size_t>(k)]);
    EXPECT_LE(session.trajectory().poses.size(), 4u + 4u / 10u);
  }
  const RecordedTrajectory trajectory = session.trajectory();
  EXPECT_EQ(trajectory.poses.size(), trajectory.stamps.size());
  EXPECT_DOUBLE_EQ(trajectory.stamps.back(), driveFrames().back().stamp);
  EXPECT_EQ(session.stats().trajectory_dropped, static_cast<std::size_t>(kSweeps) - trajectory.poses.size());
}

TEST(StampPolicyTest, ActionPerVerdict)
{
  EXPECT_FALSE(actionFor(StampVerdict::kDuplicate).process);
  EXPECT_FALSE(actionFor(StampVerdict::kOutOfOrder).process);
  EXPECT_TRUE(actionFor(StampVerdict::kJumpedBack).process && actionFor(StampVerdict::kJumpedBack).reset);
  EXPECT_TRUE(actionFor(StampVerdict::kGap).restart_motion && !actionFor(StampVerdict::kGap).reset);
  EXPECT_TRUE(actionFor(StampVerdict::kInSequence).process && !actionFor(StampVerdict::kInSequence).reset);
}

// The Pipeline (aloam_offline) applies the nodelets' time policy: a duplicate changes nothing, a jump back
// starts over exactly as a fresh pipeline.
TEST(StampPolicyTest, PipelineDropsDuplicatesAndResetsOnJumpBack)
{
  const SensorModel sensor = ts::preset("VLP16");
  PipelineConfig config;
  config.registration.sensor = sensor;
  Pipeline pipeline(config), fresh(config);
  std::vector<Cloud> sweeps;
  for (int k = 0; k < 4; ++k)
  {
    sweeps.push_back(ts::staticSweep(sensor, ts::streetPose(20.0 + kStep * k)));
    EXPECT_EQ(pipeline.process(sweeps.back(), stampOf(k), true, true).status, PipelineStatus::kOk);
  }
  const PipelineOutput duplicate = pipeline.process(sweeps[0], stampOf(3), true, true);
  EXPECT_EQ(duplicate.status, PipelineStatus::kDroppedStamp);
  EXPECT_EQ(duplicate.stamp_verdict, StampVerdict::kDuplicate);
  for (int k = 0; k < 3; ++k)
  {
    const PipelineOutput again = pipeline.process(sweeps[static_cast<std::size_t>(k)], stampOf(k) - 10.0, true, true);
    const PipelineOutput first = fresh.process(sweeps[static_cast<std::size_t>(k)], stampOf(k) - 10.0, true, true);
    EXPECT_EQ(again.stamp_verdict, k == 0 ? StampVerdict::kJumpedBack : StampVerdict::kInSequence);
    EXPECT_LT(ts::translationError(again.mapping.pose, first.mapping.pose), 1e-9) << k;
  }
}

TEST(LatestSlotTest, KeepsTheNewestAndCountsSkips)
{
  LatestSlot<int> slot;
  EXPECT_FALSE(slot.take());
  EXPECT_FALSE(slot.put(1));
  EXPECT_TRUE(slot.put(2));
  EXPECT_EQ(slot.skipped(), 1u);
  EXPECT_EQ(slot.take().value_or(0), 2);
  EXPECT_TRUE(slot.empty());
}

TEST(Rep105Test, ConjugatesByTheExtrinsic)
{
  // base_link <- sensor: the sensor 1 m up, yawed 90 deg. A sensor motion of 1 m forward along the sensor's x
  // is base_link's motion along its y.
  const Pose base_from_sensor(Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ())),
                              Eigen::Vector3d(0, 0, 1));
  const Pose sensor_motion(Eigen::Quaterniond::Identity(), Eigen::Vector3d(1, 0, 0));
  const Pose base_motion = toBaseFrame(base_from_sensor, sensor_motion);
  EXPECT_NEAR(base_motion.t.x(), 0.0, 1e-12);
  EXPECT_NEAR(base_motion.t.y(), 1.0, 1e-12);
  EXPECT_NEAR(base_motion.t.z(), 0.0, 1e-12);
  EXPECT_LT(ts::translationError(toBaseFrame(base_from_sensor, Pose()), Pose()), 1e-12);
}

}  // namespace
}  // namespace aloam
