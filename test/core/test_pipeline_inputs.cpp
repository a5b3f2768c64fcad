// Tests of Pipeline on bad input: degenerate clouds never crash, rejected sweeps leave the state untouched,
// tracking survives a poor sweep, and separate pipelines share no state.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "aloam_nodelet/core/pipeline.h"
#include "aloam_nodelet/sim/raycaster.h"
#include "aloam_nodelet/sim/scenes_extra.h"
#include "aloam_nodelet/sim/trajectories.h"
#include "test_support.h"

namespace aloam
{
namespace
{
using test_support::makePoint;
namespace ts = test_support;

constexpr int kSweeps = 8;
constexpr double kPeriod = 0.1;  // s per sweep (VLP16)
constexpr double kStartX = 40.0;
constexpr double kStep = 1.0;  // m per sweep: 10 m/s
// A second, different drive: farther along the street, offset and heading slightly left.
constexpr double kOtherStartX = 150.0;
constexpr double kOtherY = 1.0;
constexpr double kOtherYaw = 0.05;
constexpr std::size_t kBadPoints = 1000;
constexpr double kFarRange = 500.0;  // beyond the default maximum_range of 200 m
constexpr int kOnlyRing = 4;
// After a poor sweep the next good sweeps must be back within this of the truth (m).
constexpr double kMaxErrorAfterPoorSweep = 0.15;

PipelineConfig pipelineConfig()
{
  PipelineConfig config;
  config.registration.sensor = ts::preset("VLP16");
  config.registration.scan_period = config.registration.sensor.scanPeriod();
  return config;
}

Eigen::Isometry3d drivePose(int k)
{
  return ts::streetPose(kStartX + kStep * k);
}

Eigen::Isometry3d otherDrivePose(int k)
{
  return ts::poseFrom(kOtherStartX + kStep * k * std::cos(kOtherYaw), kOtherY + kStep * k * std::sin(kOtherYaw),
                      ts::kSensorHeight, kOtherYaw);
}

// Static VLP16 sweeps of both drives, ray-cast once per process.
const std::vector<Cloud>& driveSweeps()
{
  static const std::vector<Cloud> sweeps = []
  {
    std::vector<Cloud> v;
    for (int k = 0; k < kSweeps; ++k)
    {
      v.push_back(ts::staticSweep(ts::preset("VLP16"), drivePose(k)));
    }
    return v;
  }();
  return sweeps;
}

const std::vector<Cloud>& otherDriveSweeps()
{
  static const std::vector<Cloud> sweeps = []
  {
    std::vector<Cloud> v;
    for (int k = 0; k < kSweeps; ++k)
    {
      v.push_back(ts::staticSweep(ts::preset("VLP16"), otherDrivePose(k)));
    }
    return v;
  }();
  return sweeps;
}

Cloud repeated(const Point& p, std::size_t n)
{
  Cloud c;
  for (std::size_t i = 0; i < n; ++i)
  {
    Point q = p;
    q.time = static_cast<float>(kPeriod * static_cast<double>(i) / static_cast<double>(n));
    c.push_back(q);
  }
  return c;
}

struct BadInput
{
  std::string name;
  Cloud cloud;
  bool must_reject;               // nothing usable in it: the pipeline has to reject it ...
  bool only_with_fields = false;  // ... when its ring and time fields are used
};

// Every degenerate input the pipeline must survive.
std::vector<BadInput> badInputs()
{
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  std::vector<BadInput> inputs;
  inputs.push_back({ "empty", Cloud(), true });

  Cloud three;
  three.push_back(makePoint(5.0, 0.0, 0.0, 7));
  three.push_back(makePoint(5.0, 0.1, 0.0, 7));
  three.push_back(makePoint(5.0, 0.2, 0.0, 7));
  inputs.push_back({ "three points", three, true });

  inputs.push_back({ "all NaN", repeated(makePoint(nan, nan, nan, 3), kBadPoints), true });
  Cloud infs;
  for (std::size_t i = 0; i < kBadPoints; ++i)
  {
    infs.push_back(makePoint(i % 2 == 0 ? inf : 1.0, i % 2 == 0 ? 1.0 : -inf, 0.0, 3));
  }
  inputs.push_back({ "all Inf", infs, true });
  inputs.push_back({ "all at the origin", repeated(makePoint(0.0, 0.0, 0.0, 3), kBadPoints), true });

  Cloud far;
  for (std::size_t i = 0; i < kBadPoints; ++i)
  {
    const double azimuth = 2.0 * M_PI * static_cast<double>(i) / kBadPoints;
    far.push_back(makePoint(kFarRange * std::cos(azimuth), kFarRange * std::sin(azimuth), 0.0, 7));
  }
  inputs.push_back({ "beyond max range", far, true });

  // Ring fields past any sensor (garbage) and NaN times.
  Cloud garbage_fields = driveSweeps()[0];
  for (Point& p : garbage_fields.points)
  {
    p.ring = std::numeric_limits<std::uint16_t>::max();
    p.time = nan;
  }
  inputs.push_back({ "garbage ring fields", garbage_fields, true, true });

  // These may be accepted, but must leave finite poses.
  Cloud one_ring;
  for (const Point& p : driveSweeps()[0].points)
  {
    if (p.ring == kOnlyRing)
    {
      one_ring.push_back(p);
    }
  }
  inputs.push_back({ "one ring only", one_ring, false });
  inputs.push_back({ "one point repeated", repeated(makePoint(10.0, 2.0, 0.1, 7), kBadPoints), false });
  return inputs;
}

void expectFinite(const PipelineOutput& out, const std::string& what)
{
  EXPECT_TRUE(out.odometry.pose.isFinite()) << what;
  EXPECT_TRUE(out.odometry.motion.isFinite()) << what;
  EXPECT_TRUE(out.mapping.pose.isFinite()) << what;
  EXPECT_TRUE(out.mapping.correction.isFinite()) << what;
}

bool samePose(const Pose& a, const Pose& b)
{
  return a.t == b.t && a.q.coeffs() == b.q.coeffs();
}
}  // namespace

// Each degenerate cloud, to a fresh pipeline and with or without fields: rejected, or accepted with finite
// poses; never a crash.
TEST(PipelineInputsTest, DegenerateCloudsNeverCrash)
{
  for (const BadInput& input : badInputs())
  {
    for (const bool fields : { true, false })
    {
      Pipeline pipeline(pipelineConfig());
      const PipelineOutput out = pipeline.process(input.cloud, kPeriod, fields, fields);
      ASSERT_NE(out.features, nullptr) << input.name;
      if (input.must_reject && (fields || !input.only_with_fields))
      {
        EXPECT_EQ(out.status, PipelineStatus::kRejectedInput) << input.name << " fields " << fields;
      }
      if (out.status == PipelineStatus::kOk)
      {
        expectFinite(out, input.name);
      }
      // The pipeline still accepts a good sweep afterwards and starts from it.
      const PipelineOutput good = pipeline.process(driveSweeps()[1], 2.0 * kPeriod, true, true);
      EXPECT_EQ(good.status, PipelineStatus::kOk) << input.name;
      expectFinite(good, input.name);
    }
  }
}

// Rejected sweeps in the middle of a drive change nothing: the drive ends bit-for-bit where it ends
// without them.
TEST(PipelineInputsTest, RejectedSweepsLeaveStateUntouched)
{
  const std::vector<Cloud>& sweeps = driveSweeps();
  Pipeline clean(pipelineConfig());
  Pipeline disturbed(pipelineConfig());
  constexpr int kDisturbAfter = 3;
  PipelineOutput clean_out, disturbed_out;
  for (int k = 0; k < kSweeps; ++k)
  {
    const double stamp = kPeriod * (k + 1);
    clean_out = clean.process(sweeps[static_cast<std::size_t>(k)], stamp, true, true);
    disturbed_out = disturbed.process(sweeps[static_cast<std::size_t>(k)], stamp, true, true);
    EXPECT_TRUE(samePose(clean_out.mapping.pose, disturbed_out.mapping.pose)) << "sweep " << k;
    EXPECT_TRUE(samePose(clean_out.odometry.pose, disturbed_out.odometry.pose)) << "sweep " << k;
    if (k == kDisturbAfter)
    {
      int bad = 0;
      for (const BadInput& input : badInputs())
      {
        if (!input.must_reject)
        {
          continue;
        }
        // Each with a stamp of its own between two sweeps (a repeated stamp would be dropped as a duplicate).
        const double bad_stamp = stamp + 0.01 * kPeriod * ++bad;
        const PipelineOutput rejected = disturbed.process(input.cloud, bad_stamp, true, true);
        EXPECT_EQ(rejected.status, PipelineStatus::kRejectedInput) << input.name;
      }
    }
  }
  EXPECT_EQ(clean.mapping().map().cornerCount(), disturbed.mapping().map().cornerCount());
  EXPECT_EQ(clean.mapping().map().surfCount(), disturbed.mapping().map().surfCount());
}

// A poor but accepted sweep (one ring, or one repeated point) in the middle of a drive: every pose stays
// finite and the following good sweeps are back on the true trajectory.
// exposes bug: odometry reports kOk for such a sweep although its features constrain only part of the
// motion (the solve returns an arbitrary motion, e.g. (-0.36, -0.04, -0.27) m instead of (1, 0, 0) m);
// the wrong pose reaches the motion prior and the map, and the next good sweeps stay 0.8-2.5 m off.
TEST(PipelineInputsTest, TrackingSurvivesPoorSweep)
{
  const std::vector<Cloud>& sweeps = driveSweeps();
  constexpr int kPoorAt = 4;  // this sweep is replaced by the poor one
  const Eigen::Isometry3d origin = drivePose(0);
  for (const BadInput& input : badInputs())
  {
    if (input.must_reject)
    {
      continue;
    }
    Pipeline pipeline(pipelineConfig());
    double worst_after = 0.0;
    for (int k = 0; k < kSweeps; ++k)
    {
      const double stamp = kPeriod * (k + 1);
      const Cloud& cloud = k == kPoorAt ? input.cloud : sweeps[static_cast<std::size_t>(k)];
      const PipelineOutput out = pipeline.process(cloud, stamp, true, true);
      if (out.status == PipelineStatus::kOk)
      {
        expectFinite(out, input.name);
      }
      if (k > kPoorAt)
      {
        ASSERT_EQ(out.status, PipelineStatus::kOk) << input.name;
        const Pose truth = ts::toPose(origin.inverse() * drivePose(k));
        worst_after = std::max(worst_after, ts::translationError(out.mapping.pose, truth));
      }
    }
    std::printf("[ measured ] after a poor sweep (%s): worst mapped error %.4f m\n", input.name.c_str(), worst_after);
    EXPECT_LE(worst_after, kMaxErrorAfterPoorSweep) << input.name;
  }
}

// Two pipelines fed two different drives interleaved give exactly the results each gives alone.
TEST(PipelineInputsTest, PipelinesShareNoState)
{
  const std::vector<Cloud>& a = driveSweeps();
  const std::vector<Cloud>& b = otherDriveSweeps();
  std::vector<PipelineOutput> alone_a, alone_b;
  {
    Pipeline pa(pipelineConfig());
    for (int k = 0; k < kSweeps; ++k)
    {
      alone_a.push_back(pa.process(a[static_cast<std::size_t>(k)], kPeriod * (k + 1), true, true));
    }
    Pipeline pb(pipelineConfig());
    for (int k = 0; k < kSweeps; ++k)
    {
      alone_b.push_back(pb.process(b[static_cast<std::size_t>(k)], kPeriod * (k + 1), true, true));
    }
  }
  Pipeline pa(pipelineConfig());
  Pipeline pb(pipelineConfig());
  for (int k = 0; k < kSweeps; ++k)
  {
    const std::size_t i = static_cast<std::size_t>(k);
    const PipelineOutput out_b = pb.process(b[i], kPeriod * (k + 1), true, true);
    const PipelineOutput out_a = pa.process(a[i], kPeriod * (k + 1), true, true);
    EXPECT_TRUE(samePose(out_a.mapping.pose, alone_a[i].mapping.pose)) << "sweep " << k;
    EXPECT_TRUE(samePose(out_a.odometry.pose, alone_a[i].odometry.pose)) << "sweep " << k;
    EXPECT_TRUE(samePose(out_b.mapping.pose, alone_b[i].mapping.pose)) << "sweep " << k;
    EXPECT_TRUE(samePose(out_b.odometry.pose, alone_b[i].odometry.pose)) << "sweep " << k;
    EXPECT_EQ(out_a.features->sharp.size(), alone_a[i].features->sharp.size());
    EXPECT_EQ(out_b.mapping.map_surfs, alone_b[i].mapping.map_surfs);
  }
  // The drives differ, so identical results cannot come from one shared state.
  EXPECT_FALSE(samePose(alone_a.back().mapping.pose, alone_b.back().mapping.pose));
  // Both drives are tracked (the second is not disturbed by the first).
  const Pose truth_b = ts::toPose(otherDrivePose(0).inverse() * otherDrivePose(kSweeps - 1));
  EXPECT_LE(ts::translationError(alone_b.back().mapping.pose, truth_b), kMaxErrorAfterPoorSweep);
}

// A hand-held VLP-16 walk down the simulated corridor (3 s). With leaves sized for a street (leaf_min_scale
// 1) mapping finds one or two weak directions in nearly every frame (measured: height coupled with pitch,
// and roll: the 16 beams see little floor and ceiling), so with the all-or-nothing fallback every frame
// keeps the whole prediction and the estimate is lost; remapping keeps the prediction only along the weak
// directions, entirely (hard) or in part (soft, the default). Measured (seed 1): final error all-or-nothing
// 4.06 m, hard 0.11 m, soft 0.11 m (hard 0.08 m before mapping's edges needed a bend across the ring:
// ScanRegistrationConfig::curvature_across_ring). Over the randomized office and stairwell families soft
// halves the error (docs/accuracy_families.md), so the bounds here keep both far from the fallback. With the
// default leaves, which shrink to a quarter in this corridor, the denser map pins the walk down in most
// frames (measured: 12 of 30 remapped, final error 0.058 m; 2-3 of 30 and 0.085 m while mapping still
// matched the wall points that only look sharp because their spacing grows, which held it but pulled it back).
TEST(PipelineInputsTest, CorridorRemappingKeepsOnlyTheWeakDirection)
{
  const SensorModel sensor = ts::preset("VLP16");
  const sim::Scene scene = sim::corridorScene(1);
  const sim::PoseFunction walk = sim::handHeld(sim::HandHeldOptions());
  constexpr int kCorridorSweeps = 30;
  enum Mode
  {
    kFallback,
    kHard,
    kSoft,
    kSceneLeaves
  };
  const char* const names[] = { "all-or-nothing", "hard remap", "soft remap", "soft remap, scene leaves" };
  double final_error[4] = { 0.0, 0.0, 0.0, 0.0 }, odometry_error[4] = { 0.0, 0.0, 0.0, 0.0 };
  std::size_t remapped[4] = { 0, 0, 0, 0 }, degraded[4] = { 0, 0, 0, 0 };
  for (const Mode mode : { kFallback, kHard, kSoft, kSceneLeaves })
  {
    PipelineConfig config = pipelineConfig();
    config.odometry.deskew = true;
    config.odometry.degeneracy_remap = mode != kFallback;
    config.mapping.degeneracy_remap = mode != kFallback;
    config.mapping.soft_remap = mode == kSoft || mode == kSceneLeaves;
    config.odometry.soft_remap = config.mapping.soft_remap;
    if (mode != kSceneLeaves)
    {
      config.mapping.leaf_min_scale = 1.0;
    }
    Pipeline pipeline(config);
    const Eigen::Isometry3d first_end = walk(kPeriod);
    for (int k = 0; k < kCorridorSweeps; ++k)
    {
      const double start = k * kPeriod;
      sim::ScanOptions options;
      options.seed = static_cast<unsigned>(k + 1);
      const Cloud cloud = sim::scan(
          scene, sensor, [&](double t) { return walk(start + t); }, options);
      const PipelineOutput out = pipeline.process(cloud, start + kPeriod, true, true);
      ASSERT_EQ(out.status, PipelineStatus::kOk);
      remapped[mode] += out.mapping.status == MappingStatus::kRemapped;
      degraded[mode] += out.mapping.status == MappingStatus::kDegraded;
      if (mode != kFallback && out.mapping.status == MappingStatus::kRemapped)
      {
        // Reported directions: unit 6-vectors, weaker than min_constraint.
        ASSERT_FALSE(out.mapping.degenerate.empty());
        for (const DegenerateDirection& d : out.mapping.degenerate)
        {
          EXPECT_NEAR(d.rotation.squaredNorm() + d.translation.squaredNorm(), 1.0, 1e-9);
          EXPECT_LT(d.eigenvalue, config.mapping.min_constraint);
        }
        if (mode == kSoft && k % 10 == 5)
        {
          std::printf("[ measured ] corridor sweep %d: mapping degenerate along %s\n", k,
                      describe(out.mapping.degenerate).c_str());
        }
      }
      const Pose truth = ts::toPose(first_end.inverse() * walk(start + kPeriod));
      final_error[mode] = ts::translationError(out.mapping.pose, truth);
      odometry_error[mode] = ts::translationError(out.odometry.pose, truth);
    }
    std::printf(
        "[ measured ] corridor walk, %s: final error %.3f m, odometry alone %.3f m (%zu remapped, %zu "
        "degraded)\n",
        names[mode], final_error[mode], odometry_error[mode], remapped[mode], degraded[mode]);
  }
  EXPECT_GT(degraded[kFallback], kCorridorSweeps / 2u);
  for (const Mode mode : { kHard, kSoft })
  {
    EXPECT_GT(remapped[mode], kCorridorSweeps / 2u) << names[mode];
    EXPECT_EQ(degraded[mode], 0u) << names[mode];
    EXPECT_LT(final_error[mode], 0.5 * final_error[kFallback]) << names[mode];
  }
  EXPECT_LT(final_error[kHard], 0.15);
  EXPECT_LT(final_error[kSoft], 0.3);
  // Odometry's soft remapping keeps part of the step along its weak directions, which here are weak but
  // real (measured: odometry alone 0.368 m soft, 0.402 m hard).
  EXPECT_LT(odometry_error[kSoft], odometry_error[kHard]);
  EXPECT_LT(remapped[kSceneLeaves], kCorridorSweeps / 2u);
  EXPECT_EQ(degraded[kSceneLeaves], 0u);
  EXPECT_LT(final_error[kSceneLeaves], 0.15);
}

}  // namespace aloam
