// Loop closure: the pose graph, the place descriptor, keyframes with verification against drifted poses,
// look-alike places that must not close, and the pipeline with loop closure on and off.
#include <gtest/gtest.h>

#include <cmath>
#include <algorithm>
#include <cstdio>
#include <optional>
#include <vector>

#include "aloam_nodelet/core/graph_file.h"
#include "aloam_nodelet/core/laser_odometry.h"
#include "aloam_nodelet/core/loop_closure.h"
#include "aloam_nodelet/core/mapping_session.h"
#include "aloam_nodelet/core/pipeline.h"
#include "aloam_nodelet/core/pose_graph.h"
#include "aloam_nodelet/core/scan_context.h"
#include "aloam_nodelet/core/scan_registration.h"
#include "test_support.h"

namespace aloam
{
namespace
{
namespace ts = test_support;

Pose yawPose(double x, double y, double yaw)
{
  return Pose(Eigen::Quaterniond(Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ())), Eigen::Vector3d(x, y, 0.0));
}

// A circle of n poses; odometry measured with a yaw bias per step, chained into the initial guess.
struct Circle
{
  std::vector<Pose> truth;
  PoseGraph graph;
};

Circle driftedCircle(int n, double radius, double yaw_bias)
{
  Circle c;
  for (int i = 0; i < n; ++i)
  {
    const double a = 2.0 * M_PI * i / n;
    c.truth.push_back(yawPose(radius * std::sin(a), radius * (1.0 - std::cos(a)), a));
  }
  Pose chained = c.truth[0];
  c.graph.addNode(chained);
  for (int i = 1; i < n; ++i)
  {
    const Pose step = c.truth[i - 1].inverse() * c.truth[i] * yawPose(0.0, 0.0, yaw_bias);
    chained = chained * step;
    c.graph.addNode(chained);
    PoseGraphEdge e;
    e.from = i - 1;
    e.to = i;
    e.measured = step;
    // Sigmas as LoopClosure gives odometry edges of this length.
    const LoopClosureConfig config;
    const double length = step.t.norm();
    e.sqrt_information =
        sqrtInformation(config.odometry_sigma_translation * length, config.odometry_sigma_rotation * length);
    c.graph.addEdge(e);
  }
  return c;
}

double worstError(const PoseGraph& graph, const std::vector<Pose>& truth)
{
  double worst = 0.0;
  for (std::size_t i = 0; i < truth.size(); ++i)
  {
    worst = std::max(worst, ts::translationError(graph.pose(i), truth[i]));
  }
  return worst;
}

TEST(PoseGraphTest, LoopEdgeRemovesTheDriftOfACircle)
{
  // 0.15 deg of yaw per 3.1 m step: 0.05 deg/m, LOAM on a bad day.
  Circle c = driftedCircle(40, 20.0, 0.15 * ts::kDegToRad);
  const double before = worstError(c.graph, c.truth);
  PoseGraphEdge loop;
  loop.from = 0;
  loop.to = 39;
  loop.measured = c.truth[0].inverse() * c.truth[39];
  loop.loop = true;
  loop.sqrt_information = sqrtInformation(0.1, 0.01);
  c.graph.addEdge(loop);
  const PoseGraphSummary s = c.graph.optimize();
  ASSERT_TRUE(s.solved);
  const double after = worstError(c.graph, c.truth);
  std::printf("[ measured ] circle of 40 poses: worst error %.2f m before, %.2f m after (%.1f ms)\n", before, after,
              s.ms);
  EXPECT_GT(before, 1.5);
  EXPECT_LT(after, 0.25 * before);
  EXPECT_LT(c.graph.whitenedError(c.graph.edges().size() - 1), 1.0);
  // The first pose is the map's origin: it never moves.
  EXPECT_LT(ts::translationError(c.graph.pose(0), c.truth[0]), 1e-9);
}

TEST(PoseGraphTest, AFalseLoopAmongTrueOnesIsLeftOut)
{
  // No drift at all; one true loop, and one false loop claiming that the far side of the circle is the start.
  auto build = [](bool robust)
  {
    Circle c = driftedCircle(40, 20.0, 0.0);
    for (const auto& [from, to, measured] :
         { std::tuple<std::size_t, std::size_t, Pose>{ 0, 39, Pose() }, { 0, 20, Pose() } })
    {
      PoseGraphEdge e;
      e.from = from;
      e.to = to;
      e.measured = to == 39 ? c.truth[0].inverse() * c.truth[39] : measured;
      e.loop = true;
      e.sqrt_information =
          sqrtInformation(LoopClosureConfig().loop_sigma_translation, LoopClosureConfig().loop_sigma_rotation);
      c.graph.addEdge(e);
    }
    PoseGraphOptions options;
    options.outlier_error = robust ? PoseGraphOptions().outlier_error : 1e9;
    options.loop_loss_scale = robust ? PoseGraphOptions().loop_loss_scale : 0.0;
    const PoseGraphSummary s = c.graph.optimize(options);
    EXPECT_TRUE(s.solved);
    EXPECT_EQ(s.disabled.size(), robust ? 1u : 0u);
    if (robust && !s.disabled.empty())
    {
      EXPECT_EQ(c.graph.edges()[s.disabled[0]].to, 20u);  // the false one
      EXPECT_FALSE(c.graph.edges()[s.disabled[0]].enabled);
    }
    return worstError(c.graph, c.truth);
  };
  const double robust = build(true), plain = build(false);
  std::printf("[ measured ] a false loop 40 m off: worst error %.2f m with the robust loss, %.2f m without\n", robust,
              plain);
  EXPECT_GT(plain, 10.0);
  EXPECT_LT(robust, 0.5 * plain);
}

TEST(PoseGraphTest, RejectsEdgesItCannotUse)
{
  PoseGraph g;
  g.addNode(Pose());
  g.addNode(Pose());
  PoseGraphEdge e;
  e.from = 0;
  e.to = 2;
  EXPECT_THROW(g.addEdge(e), std::invalid_argument);
  e.to = 1;
  e.sqrt_information.setZero();
  EXPECT_THROW(g.addEdge(e), std::invalid_argument);
  e.sqrt_information = Eigen::Matrix<double, 6, 6>::Identity();
  e.sqrt_information(2, 2) = std::nan("");
  EXPECT_THROW(g.addEdge(e), std::invalid_argument);
  EXPECT_FALSE(g.optimize().solved);  // no edge: nothing to solve
}

TEST(PoseGraphTest, AWeakLoopDirectionCarriesOnlyItsShare)
{
  // Registered weak along the current keyframe's x (none of the constraint) and about its z (a quarter);
  // the current keyframe is turned 90 deg from the target, so its x is the target's y.
  DegenerateDirection along_x, about_z;
  along_x.translation = Eigen::Vector3d::UnitX();
  along_x.share = 0.0;
  const double lever_arm = 3.0;
  about_z.rotation = lever_arm * Eigen::Vector3d::UnitZ();
  about_z.rotation.normalize();  // a unit 6-vector, as PoseProblem::degeneracy gives them
  about_z.share = 0.25;
  const Eigen::Quaterniond turned(Eigen::AngleAxisd(M_PI / 2.0, Eigen::Vector3d::UnitZ()));
  const Eigen::Matrix<double, 6, 6> root = loopSqrtInformation(0.1, 0.01, { along_x, about_z }, turned, lever_arm);
  const Eigen::Matrix<double, 6, 6> information = root.transpose() * root;
  auto along = [&](const Eigen::Matrix<double, 6, 1>& v) { return v.dot(information * v); };
  Eigen::Matrix<double, 6, 1> v;
  v << 0.0, 1.0, 0.0, 0.0, 0.0, 0.0;  // the target's y: the current keyframe's x
  EXPECT_NEAR(along(v), 0.0, 1e-6);
  v << 1.0, 0.0, 0.0, 0.0, 0.0, 0.0;
  EXPECT_NEAR(along(v), 100.0, 1e-6);
  v << 0.0, 0.0, 1.0, 0.0, 0.0, 0.0;
  EXPECT_NEAR(along(v), 100.0, 1e-6);
  v << 0.0, 0.0, 0.0, 0.0, 0.0, 1.0;  // yaw: a quarter of 1 / 0.01^2
  EXPECT_NEAR(along(v), 0.25 * 1e4, 1e-3);
  v << 0.0, 0.0, 0.0, 1.0, 0.0, 0.0;
  EXPECT_NEAR(along(v), 1e4, 1e-3);
  // Nothing weak: the plain sigmas.
  EXPECT_TRUE(loopSqrtInformation(0.1, 0.01, {}, turned, lever_arm).isApprox(sqrtInformation(0.1, 0.01), 1e-9));

  // In a graph, such a loop holds the directions it knows and leaves the weak one to the odometry: a chain
  // drifted 2 m along the target's y and 1 m along z is pulled back along z only.
  PoseGraph graph;
  graph.addNode(Pose());
  graph.addNode(Pose(turned, Eigen::Vector3d(10.0, 2.0, 1.0)));
  PoseGraphEdge odometry;
  odometry.from = 0;
  odometry.to = 1;
  odometry.measured = Pose(turned, Eigen::Vector3d(10.0, 2.0, 1.0));
  odometry.sqrt_information = sqrtInformation(1.0, 0.01);
  graph.addEdge(odometry);
  PoseGraphEdge loop;
  loop.from = 0;
  loop.to = 1;
  loop.loop = true;
  loop.measured = Pose(turned, Eigen::Vector3d(10.0, 0.0, 0.0));
  loop.sqrt_information = root;
  graph.addEdge(loop);
  PoseGraphOptions options;
  options.loop_loss_scale = 0.0;
  ASSERT_TRUE(graph.optimize(options).solved);
  EXPECT_NEAR(graph.pose(1).t.y(), 2.0, 1e-3);   // the weak direction: as odometry has it
  EXPECT_NEAR(graph.pose(1).t.z(), 0.01, 0.01);  // pulled to the loop (1 m odometry sigma against 0.1)
  EXPECT_NEAR(graph.pose(1).t.x(), 10.0, 1e-3);
}

// Edge and plane features of one noise-free sweep of the street.
struct Features
{
  Cloud corners, surfs, full;
};

Features featuresAt(const sim::Scene& scene, const SensorModel& sensor, const Eigen::Isometry3d& pose)
{
  ScanRegistrationConfig config;
  config.sensor = sensor;
  config.scan_period = sensor.scanPeriod();
  ScanRegistration registration(config);
  FeatureSet fs;
  const Cloud sweep = sim::scan(
      scene, sensor, [&](double) { return pose; }, sim::ScanOptions{});
  EXPECT_TRUE(registration.process(sweep, 0.0, true, true, fs));
  return Features{ fs.less_sharp, fs.less_flat, fs.full };
}

TEST(ScanContextTest, SamePlaceTurnedMatchesWithItsYaw)
{
  const SensorModel sensor = ts::preset("VLP16");
  const Features a = featuresAt(ts::streetScene(), sensor, ts::streetPose(60.0));
  const Features b = featuresAt(ts::streetScene(), sensor, ts::streetPose(60.5, 0.5, 70.0 * ts::kDegToRad));
  const Features far = featuresAt(ts::streetScene(), sensor, ts::streetPose(160.0));
  const ScanContext sa = ScanContext::compute(a.full, Cloud(), Pose());
  const ScanContext sb = ScanContext::compute(b.full, Cloud(), Pose());
  const ScanContext sf = ScanContext::compute(far.full, Cloud(), Pose());
  const ScanContextMatch same = sb.match(sa);
  const ScanContextMatch other = sf.match(sa);
  std::printf("[ measured ] descriptor distance: same place turned 70 deg %.3f (yaw %.1f deg), 100 m on %.3f\n",
              same.distance, same.yaw * ts::kRadToDeg, other.distance);
  EXPECT_NEAR(same.yaw * ts::kRadToDeg, 70.0, 9.0);
  EXPECT_LT(same.distance, other.distance);
  EXPECT_EQ(sa.ringKey().size(), ScanContextConfig().rings);
}

TEST(ScanContextTest, LevellingUsesRollAndPitchOnly)
{
  const Pose tilted(Eigen::Quaterniond(Eigen::AngleAxisd(1.0, Eigen::Vector3d::UnitZ()) *
                                       Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitY())),
                    Eigen::Vector3d(5.0, 2.0, 1.0));
  EXPECT_NEAR(yawOf(tilted), 1.0, 1e-9);
  EXPECT_NEAR(yawOf(Pose(levelling(tilted), Eigen::Vector3d::Zero())), 0.0, 1e-9);
}

// Out along the street, a U-turn of radius 3 m, and back on the other side: the second half revisits the
// first in the opposite direction.
ts::Trajectory outAndBack(double start_x, double length, double speed)
{
  constexpr double kRadius = 3.0;
  return [=](double t)
  {
    const double t1 = length / speed, t2 = t1 + M_PI * kRadius / speed;
    if (t < t1)
    {
      return ts::poseFrom(start_x + speed * t, -kRadius, ts::kSensorHeight, 0.0);
    }
    if (t < t2)
    {
      const double a = (t - t1) * speed / kRadius;
      return ts::poseFrom(start_x + length + kRadius * std::sin(a), -kRadius * std::cos(a), ts::kSensorHeight, a);
    }
    return ts::poseFrom(start_x + length - speed * (t - t2), kRadius, ts::kSensorHeight, M_PI);
  };
}

double outAndBackDuration(double length, double speed)
{
  return 2.0 * length / speed + M_PI * 3.0 / speed;
}

LoopClosureConfig shortRunConfig()
{
  LoopClosureConfig config;
  config.min_loop_separation_time = 5.0;  // the test drives are short
  return config;
}

// Feeds keyframe-spaced sweeps of a drive to a LoopClosure with odometry that drifts: each step's yaw is off
// by `yaw_bias` and its length by `scale`. Returns the truth of every offered frame (relative to the first).
struct DriftedRun
{
  std::vector<Pose> truth, input;
  std::vector<double> stamps;
};

DriftedRun runDrifted(LoopClosure& loops, const sim::Scene& scene, const ts::Trajectory& drive, double duration,
                      double step_s, double yaw_bias, double scale)
{
  const SensorModel sensor = ts::preset("VLP16");
  DriftedRun run;
  const Eigen::Isometry3d origin = drive(0.0);
  Pose drifted, fix;
  Pose last_truth;
  for (double t = 0.0; t <= duration; t += step_s)
  {
    const Pose truth = ts::toPose(origin.inverse() * drive(t));
    if (!run.truth.empty())
    {
      Pose step = last_truth.inverse() * truth;
      step.t *= scale;
      drifted = drifted * step * yawPose(0.0, 0.0, yaw_bias);
    }
    last_truth = truth;
    const Features f = featuresAt(scene, sensor, drive(t));
    const Pose input = fix * drifted;
    const LoopUpdate u = loops.addFrame(t, input, f.corners, f.surfs, &f.full);
    if (u.optimized)
    {
      fix = u.correction * fix;
    }
    run.truth.push_back(truth);
    run.input.push_back(u.optimized ? u.correction * input : input);
    run.stamps.push_back(t);
  }
  return run;
}

TEST(LoopClosureTest, ClosesADriftedOutAndBackDriveWithTheTrueRelativePose)
{
  LoopClosure loops(shortRunConfig());
  constexpr double kLength = 70.0, kSpeed = 4.0;
  // About what LOAM drifts by on a bad day: 0.04 deg of yaw and 1 % of length per metre.
  constexpr double kYawBias = 0.04 * ts::kDegToRad, kScale = 1.01;
  const ts::Trajectory drive = outAndBack(20.0, kLength, kSpeed);
  const DriftedRun run =
      runDrifted(loops, ts::streetScene(), drive, outAndBackDuration(kLength, kSpeed), 0.25, kYawBias, kScale);

  const auto& kf = loops.keyframes();
  int accepted = 0;
  std::vector<double> solved_errors;
  for (const LoopRecord& r : loops.history())
  {
    std::printf("[ measured ] loop %zu -> %zu (%s): %s%s, share %.2f, residual %.3f m, moves %.2f m\n", r.from, r.to,
                r.source == LoopSource::kNearby ? "nearby" : "descriptor",
                r.accepted ? "accepted" : "rejected: ", r.reason.c_str(), r.fitness.inlier_share,
                r.fitness.mean_residual, r.correction_m);
    if (!r.accepted)
    {
      continue;
    }
    ++accepted;
    const Pose truth_from = run.truth[kf[r.from].stamp == 0.0 ? 0 : std::size_t(std::lround(kf[r.from].stamp / 0.25))];
    const Pose truth_to = run.truth[std::size_t(std::lround(kf[r.to].stamp / 0.25))];
    const Pose truth_rel = truth_from.inverse() * truth_to;
    EXPECT_LT(ts::translationError(r.relative, truth_rel), 0.3);
    EXPECT_LT(ts::rotationErrorDeg(r.relative, truth_rel), 1.0);
    // The revisited place agrees in the solved graph: the two keyframes sit as they truly do.
    const Pose solved_rel = kf[r.from].pose.inverse() * kf[r.to].pose;
    solved_errors.push_back(ts::translationError(solved_rel, truth_rel));
  }
  std::sort(solved_errors.begin(), solved_errors.end());
  ASSERT_FALSE(solved_errors.empty());
  std::printf(
      "[ measured ] accepted loops in the solved graph: median %.2f m, worst %.2f m off the true relative pose\n",
      solved_errors[solved_errors.size() / 2], solved_errors.back());
  EXPECT_LT(solved_errors[solved_errors.size() / 2], 0.3);
  EXPECT_LT(solved_errors.back(), 0.8);
  EXPECT_GE(accepted, 2);

  // The return leg's keyframes: far closer to the truth after the graph than as odometry gave them.
  double before = 0.0, after = 0.0;
  int n = 0;
  for (std::size_t i = 0; i < kf.size(); ++i)
  {
    const std::size_t frame = std::size_t(std::lround(kf[i].stamp / 0.25));
    if (kf[i].stamp < 0.6 * outAndBackDuration(kLength, kSpeed))
    {
      continue;
    }
    // What odometry alone said: the drifted chain without any correction.
    Pose chained;
    for (std::size_t j = 1; j <= frame; ++j)
    {
      Pose step = run.truth[j - 1].inverse() * run.truth[j];
      step.t *= kScale;
      chained = chained * step * yawPose(0.0, 0.0, kYawBias);
    }
    before += ts::translationError(chained, run.truth[frame]);
    after += ts::translationError(kf[i].pose, run.truth[frame]);
    ++n;
  }
  ASSERT_GT(n, 10);
  std::printf("[ measured ] return leg, %d keyframes: mean error %.2f m from odometry, %.2f m after loop closure\n", n,
              before / n, after / n);
  // What remains is mostly the 1 % scale error of the way out, which no revisit can see.
  EXPECT_LT(after, 0.4 * before);
  const LoopClosureStats s = loops.stats();
  EXPECT_EQ(s.accepted, static_cast<std::size_t>(accepted));
  EXPECT_GT(s.cloud_bytes, 0u);
}

// Identical blocks every 40 m on both sides of a straight road: every block looks like the last one.
sim::Scene repeatedBlocks()
{
  sim::Scene scene;
  scene.add(sim::PlanePatch::horizontal(0.0, -100.0, 500.0, -100.0, 100.0), sim::SurfaceClass::Ground);
  for (int b = 0; b < 10; ++b)
  {
    const double x = 40.0 * b;
    for (const double side : { -1.0, 1.0 })
    {
      scene.add(sim::OrientedBox(Eigen::Vector3d(x + 8.0, side * 14.0, 6.0), Eigen::Vector3d(8.0, 5.0, 6.0)),
                sim::SurfaceClass::Building);
      scene.add(sim::OrientedBox(Eigen::Vector3d(x + 26.0, side * 13.0, 4.0), Eigen::Vector3d(6.0, 4.0, 4.0)),
                sim::SurfaceClass::Building);
      scene.add(sim::VerticalCylinder(x + 18.0, side * 7.0, 0.15, 0.0, 6.0), sim::SurfaceClass::Pole);
      scene.add(sim::OrientedBox(Eigen::Vector3d(x + 33.0, side * 6.5, 0.8), Eigen::Vector3d(2.2, 0.9, 0.8)),
                sim::SurfaceClass::Vehicle);
    }
  }
  return scene;
}

TEST(LoopClosureTest, LookAlikeBlocksNeverClose)
{
  const sim::Scene scene = repeatedBlocks();
  LoopClosure loops(shortRunConfig());
  const ts::Trajectory drive = [](double t) { return ts::poseFrom(10.0 + 6.0 * t, 0.0, ts::kSensorHeight, 0.0); };
  runDrifted(loops, scene, drive, 30.0, 0.25, 0.05 * ts::kDegToRad, 1.0);
  std::size_t descriptor_tried = 0;
  for (const LoopRecord& r : loops.history())
  {
    descriptor_tried += r.source == LoopSource::kDescriptor;
    EXPECT_FALSE(r.accepted) << "false loop " << r.from << " -> " << r.to << " moving " << r.correction_m << " m";
  }
  const LoopClosureStats s = loops.stats();
  std::printf("[ measured ] look-alike blocks: %zu keyframes, %zu loops tried (%zu by descriptor), %zu accepted\n",
              s.keyframes, s.tried, descriptor_tried, s.accepted);
  EXPECT_GT(descriptor_tried, 0u);  // the descriptor did take the blocks for the same place
  EXPECT_EQ(s.accepted, 0u);
}

TEST(LoopClosureTest, KeyframesFollowDistanceAngleAndTheCloudBound)
{
  LoopClosureConfig config;
  Cloud one = ts::cloudOf({ ts::makePoint(1.0, 2.0, 3.0) });
  config.max_keyframe_bytes = 3 * sizeof(Point);  // three keyframes of one point each
  LoopClosure loops(config);
  const Cloud none;
  EXPECT_TRUE(loops.addFrame(0.0, Pose(), one, none).keyframe);
  EXPECT_FALSE(loops.addFrame(0.1, yawPose(0.5, 0.0, 0.0), one, none).keyframe);
  EXPECT_TRUE(loops.addFrame(0.2, yawPose(1.0, 0.0, 0.0), one, none).keyframe);
  EXPECT_TRUE(loops.addFrame(0.3, yawPose(1.0, 0.0, 12.0 * ts::kDegToRad), one, none).keyframe);
  for (int i = 1; i <= 5; ++i)
  {
    loops.addFrame(0.3 + i, yawPose(1.0 + 2.0 * i, 0.0, 0.0), one, none);
  }
  const LoopClosureStats s = loops.stats();
  EXPECT_EQ(s.keyframes, 8u);
  EXPECT_EQ(s.keyframes_with_clouds, 3u);
  EXPECT_EQ(s.cloud_bytes, 3 * sizeof(Point));
  EXPECT_EQ(loops.mapSweeps().size(), 3u);
  EXPECT_EQ(loops.keyframeAt(0.25), 1u);
  EXPECT_EQ(loops.graph().edges().size(), 7u);
  EXPECT_NEAR(loops.keyframes().back().path, 11.0, 1e-9);
}

PipelineConfig streetPipeline(bool loop_closure)
{
  PipelineConfig config;
  config.registration.sensor = ts::preset("VLP16");
  config.registration.scan_period = config.registration.sensor.scanPeriod();
  config.loop_closure = loop_closure;
  config.loop = shortRunConfig();
  return config;
}

TEST(LoopClosurePipelineTest, WithoutARevisitPosesAreIdenticalWithLoopClosureOnAndOff)
{
  const SensorModel sensor = ts::preset("VLP16");
  Pipeline off(streetPipeline(false)), on(streetPipeline(true));
  for (int k = 0; k < 60; ++k)
  {
    const double t = 0.1 * (k + 1);
    const Cloud sweep = ts::staticSweep(sensor, ts::streetPose(20.0 + 8.0 * t));
    const PipelineOutput a = off.process(sweep, t, true, true);
    const PipelineOutput b = on.process(sweep, t, true, true);
    ASSERT_EQ(a.status, PipelineStatus::kOk);
    EXPECT_EQ(a.mapping.pose.t, b.mapping.pose.t) << "frame " << k;
    EXPECT_EQ(a.mapping.pose.q.coeffs(), b.mapping.pose.q.coeffs()) << "frame " << k;
  }
  ASSERT_NE(on.loopClosure(), nullptr);
  EXPECT_EQ(off.loopClosure(), nullptr);
  EXPECT_GT(on.loopClosure()->stats().keyframes, 25u);
  EXPECT_EQ(on.loopClosure()->stats().accepted, 0u);
}

TEST(LoopClosurePipelineTest, OutAndBackClosesAndEndsNearTheTruth)
{
  const SensorModel sensor = ts::preset("VLP16");
  constexpr double kLength = 60.0, kSpeed = 6.0;
  const ts::Trajectory drive = outAndBack(20.0, kLength, kSpeed);
  const double duration = outAndBackDuration(kLength, kSpeed);
  Pipeline off(streetPipeline(false)), on(streetPipeline(true));
  const Eigen::Isometry3d origin = drive(0.1);
  double ate_off = 0.0, ate_on = 0.0;
  int n = 0;
  Pose end_off, end_on, end_truth;
  for (int k = 0; 0.1 * (k + 1) <= duration; ++k)
  {
    const double t = 0.1 * (k + 1);
    const Cloud sweep = ts::staticSweep(sensor, drive(t));
    const PipelineOutput a = off.process(sweep, t, true, true);
    const PipelineOutput b = on.process(sweep, t, true, true);
    ASSERT_EQ(b.status, PipelineStatus::kOk);
    end_truth = ts::toPose(origin.inverse() * drive(t));
    end_off = a.mapping.pose;
    end_on = b.mapping.pose;
    ate_off += std::pow(ts::translationError(end_off, end_truth), 2);
    ate_on += std::pow(ts::translationError(end_on, end_truth), 2);
    ++n;
  }
  ate_off = std::sqrt(ate_off / n);
  ate_on = std::sqrt(ate_on / n);
  const LoopClosureStats s = on.loopClosure()->stats();
  for (const LoopRecord& r : on.loopClosure()->history())
  {
    std::printf("  loop %zu -> %zu %d %s share %.2f res %.3f moves %.2f\n", r.from, r.to, int(r.source),
                r.reason.c_str(), r.fitness.inlier_share, r.fitness.mean_residual, r.correction_m);
  }
  std::printf(
      "[ measured ] out and back, %d sweeps: ATE %.3f m off, %.3f m on; end %.3f / %.3f m; %zu loops "
      "accepted of %zu, %zu optimizations, last %.1f ms\n",
      n, ate_off, ate_on, ts::translationError(end_off, end_truth), ts::translationError(end_on, end_truth), s.accepted,
      s.tried, s.optimizations, s.last_optimize_ms);
  EXPECT_GE(s.accepted, 1u);
  EXPECT_LT(ts::translationError(end_on, end_truth), 0.3);
  EXPECT_LT(ate_on, ate_off + 0.05);
}

// The mapping nodelet's path: admit, register, update the map, then closeLoops() on the lane. Loops close,
// the recorded trajectory and the full-rate answer follow the corrected map, and a reset starts the loop
// closure over.
TEST(LoopClosureSessionTest, ClosesLoopsOffThePosePathAndCorrectsTheTrajectory)
{
  const SensorModel sensor = ts::preset("VLP16");
  // Under a sanitizer (10-20 times slower) the street is half as long: the same loops, lane and correction.
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
  constexpr double kLength = 30.0, kSpeed = 6.0;
#else
  constexpr double kLength = 60.0, kSpeed = 6.0;
#endif
  const ts::Trajectory drive = outAndBack(20.0, kLength, kSpeed);
  const double duration = outAndBackDuration(kLength, kSpeed);
  ScanRegistrationConfig rc;
  rc.sensor = sensor;
  ScanRegistration registration(rc);
  LaserOdometry odometry;
  MappingSessionConfig config;
  config.loop_closure = true;
  config.loop = shortRunConfig();
  MappingSession session(config);
  const Eigen::Isometry3d origin = drive(0.1);
  std::size_t optimized = 0, frames = 0, offered = 0, offered_keyframes = 0;
  Pose last_answer, first_pose;
  for (int k = 0; 0.1 * (k + 1) <= duration; ++k)
  {
    const double t = 0.1 * (k + 1);
    auto features = std::make_shared<FeatureSet>();
    ASSERT_TRUE(registration.process(ts::staticSweep(sensor, drive(t)), t, true, true, *features));
    const OdometryFrame frame = odometry.track(features);
    odometry.indexLast();
    const Admission admission = session.admit(frame, static_cast<std::int64_t>(std::llround(t * 1e9)));
    ASSERT_TRUE(admission.taken);
    last_answer = admission.corrected;
    const MappingResult registered = session.registerFrame(frame);
    if (k == 0)
    {
      first_pose = registered.pose;
    }
    session.updateMap();
    const LoopStep step = session.closeLoops();
    optimized += step.update.optimized;
    ++frames;
    offered += step.offered;
    offered_keyframes += step.update.keyframe;
    if (step.update.optimized)
    {
      EXPECT_GT(step.rebuild_ms, 0.0);
    }
  }
  const MappingSessionStats stats = session.stats();
  const RecordedTrajectory trajectory = session.trajectory();
  ASSERT_FALSE(trajectory.poses.empty());
  const Pose end_truth = ts::toPose(origin.inverse() * drive(trajectory.stamps.back()));
  const double end_error = ts::translationError(trajectory.relativeToFirst().back(), end_truth);
  std::printf(
      "[ measured ] session: %zu keyframes, %zu loops accepted of %zu, %zu graph solves; end %.3f m off; "
      "last rebuild %.1f ms\n",
      stats.loops.keyframes, stats.loops.accepted, stats.loops.tried, optimized, end_error, stats.last_rebuild_ms);
  EXPECT_GE(stats.loops.accepted, 1u);
  EXPECT_EQ(optimized, stats.loops.optimizations);
  // Only frames that become keyframes are copied and offered.
  EXPECT_EQ(offered, offered_keyframes);
  EXPECT_LT(offered, frames);
  EXPECT_LT(end_error, 0.3);
  EXPECT_GT(stats.loops.cloud_bytes, 0u);
  // The graph holds the first keyframe: the poses up to it stay where mapping put them.
  EXPECT_LT(ts::translationError(trajectory.poses.front(), first_pose), 1e-6);
  // The full-rate answer is in the corrected map: it agrees with the last recorded pose.
  EXPECT_LT(ts::translationError(last_answer, trajectory.poses.back()), 0.5);

  // Off: nothing is offered. A reset: the keyframes go with the map.
  session.setLoopClosure(false, config.loop);
  EXPECT_FALSE(session.closeLoops().offered);
  session.requestReset();
  session.setLoopClosure(true, config.loop);
  auto features = std::make_shared<FeatureSet>();
  ASSERT_TRUE(registration.process(ts::staticSweep(sensor, drive(duration)), duration + 0.1, true, true, *features));
  const OdometryFrame frame = odometry.track(features);
  session.admit(frame, static_cast<std::int64_t>(std::llround((duration + 0.1) * 1e9)));
  session.registerFrame(frame);
  session.updateMap();
  EXPECT_TRUE(session.closeLoops().offered);
  EXPECT_EQ(session.stats().loops.keyframes, 1u);
}

// Two runs in one graph (issue 24): run 1 drives out along the street and saves its graph; run 2 loads it and
// starts where run 1 started, but is told a start pose 0.64 m and 2 deg off (a robot pushed off its dock). It
// drives the same lane at another speed and on beyond run 1's end. Run 2 must tie its first keyframe to run
// 1's, end up in run 1's frame (its poses agree with run 1's where both drove, and with the truth as well as
// run 1 does), close loops with run 1's keyframes at their true relative poses, and its graph must hold run
// 1's keyframes.
struct SessionRun
{
  std::vector<Pose> poses, truth;  ///< the recorded (corrected) trajectory and the truth, in run 1's map frame
  LoopClosureStats loops;
};

SessionRun driveSession(MappingSession& session, const ts::Trajectory& drive, double duration,
                        const Eigen::Isometry3d& map_origin)
{
  const SensorModel sensor = ts::preset("VLP16");
  ScanRegistrationConfig rc;
  rc.sensor = sensor;
  ScanRegistration registration(rc);
  LaserOdometry odometry;
  for (int k = 0; 0.1 * (k + 1) <= duration; ++k)
  {
    const double t = 0.1 * (k + 1);
    auto features = std::make_shared<FeatureSet>();
    // With the motion within the sweep, which odometry deskews (a static sweep deskewed by the car's speed
    // would be a warped one).
    EXPECT_TRUE(registration.process(ts::driveSweep(sensor, drive, k, true), t, true, true, *features));
    const OdometryFrame frame = odometry.track(features);
    odometry.indexLast();
    EXPECT_TRUE(session.admit(frame, static_cast<std::int64_t>(std::llround(t * 1e9))).taken);
    session.registerFrame(frame);
    session.updateMap();
    session.closeLoops();
  }
  SessionRun run;
  const RecordedTrajectory trajectory = session.trajectory();
  run.poses = trajectory.poses;
  for (const double stamp : trajectory.stamps)
  {
    run.truth.push_back(ts::toPose(map_origin.inverse() * drive(stamp)));
  }
  run.loops = session.stats().loops;
  return run;
}

/// A straight drive along x: the estimated position where the truth was at `true_x` (linear between poses).
std::optional<Eigen::Vector3d> estimateAt(const SessionRun& run, double true_x)
{
  for (std::size_t i = 1; i < run.truth.size(); ++i)
  {
    const double a = run.truth[i - 1].t.x(), b = run.truth[i].t.x();
    if (a <= true_x && true_x <= b && b > a)
    {
      const double s = (true_x - a) / (b - a);
      return (1.0 - s) * run.poses[i - 1].t + s * run.poses[i].t;
    }
  }
  return std::nullopt;
}

TEST(LoopClosureTwoSessionsTest, ASecondRunExtendsTheSavedGraphInTheSameFrame)
{
  constexpr double kStartX = 20.0, kLane = -3.0;
  const ts::Trajectory drive1 = [](double t) { return ts::poseFrom(kStartX + 6.0 * t, kLane, ts::kSensorHeight, 0.0); };
  // Run 2 passes run 1's first pose (its first sweep ends at t = 0.1, 0.6 m on) at its own t = 0.1, slower.
  const ts::Trajectory drive2 = [](double t)
  { return ts::poseFrom(kStartX + 0.6 + 5.0 * (t - 0.1), kLane, ts::kSensorHeight, 0.0); };
  const Eigen::Isometry3d origin = drive1(0.1);
  MappingSessionConfig config;
  config.loop_closure = true;
  config.loop = shortRunConfig();

  // Run 1: 60 m out.
  MappingSession first(config);
  const SessionRun run1 = driveSession(first, drive1, 10.0, origin);
  const LoopGraph saved = first.exportGraph();
  ASSERT_GT(saved.keyframes.size(), 40u);
  const std::string path = ::testing::TempDir() + "aloam_two_sessions.graph";
  writeGraphFile(path, saved, GraphFileInfo());
  GraphFile file = readGraphFile(path);

  // Run 2: 75 m out, through run 1's 60 m and on, over run 1's graph, from a start pose told wrong.
  const Pose told(Eigen::Quaterniond(Eigen::AngleAxisd(2.0 * ts::kDegToRad, Eigen::Vector3d::UnitZ())),
                  Eigen::Vector3d(0.5, -0.4, 0.0));
  MappingSession second(config);
  EXPECT_TRUE(second.loadGraph(std::move(file.graph), told).empty());
  EXPECT_EQ(second.stats().loops.keyframes_loaded, saved.keyframes.size());
  const SessionRun run2 = driveSession(second, drive2, 15.0, origin);

  // Every accepted loop (run 2 to run 1: there is no other) against the true relative pose of the two sweeps.
  const LoopGraph both = second.exportGraph();
  const std::size_t n1 = saved.keyframes.size();
  const auto truthOf = [&](const Keyframe& k)
  { return ts::toPose(origin.inverse() * (k.session == 0 ? drive1(k.stamp) : drive2(k.stamp))); };
  int cross = 0;
  double worst_m = 0.0, worst_deg = 0.0;
  for (const PoseGraphEdge& e : both.edges)
  {
    if (!e.loop || !e.enabled)
    {
      continue;
    }
    EXPECT_TRUE(e.from < n1 && e.to >= n1) << "a loop within one run: " << e.from << " -> " << e.to;
    const Pose truth = truthOf(both.keyframes[e.from]).inverse() * truthOf(both.keyframes[e.to]);
    worst_m = std::max(worst_m, ts::translationError(e.measured, truth));
    worst_deg = std::max(worst_deg, ts::rotationErrorDeg(e.measured, truth));
    ++cross;
  }
  // Where both drove: run 2's pose against run 1's at the same true place, and both against the truth.
  double apart = 0.0, worst1 = 0.0, worst2 = 0.0;
  for (std::size_t i = 0; i < run2.poses.size(); ++i)
  {
    worst2 = std::max(worst2, ts::translationError(run2.poses[i], run2.truth[i]));
    if (const auto same_place = estimateAt(run1, run2.truth[i].t.x()))
    {
      apart = std::max(apart, (run2.poses[i].t - *same_place).norm());
    }
  }
  for (std::size_t i = 0; i < run1.poses.size(); ++i)
  {
    worst1 = std::max(worst1, ts::translationError(run1.poses[i], run1.truth[i]));
  }
  std::printf(
      "[ measured ] run 1: %zu keyframes, worst %.3f m off the truth; run 2 told a start %.2f m off: tie %s (%s), "
      "%d loop edges to run 1 (worst %.3f m / %.2f deg off the truth) of %zu tried; run 2 at most %.3f m from run "
      "1 at the same place, worst %.3f m off the truth\n",
      n1, worst1, told.t.norm(), toString(run2.loops.tie), run2.loops.tie_reason.c_str(), cross, worst_m, worst_deg,
      run2.loops.tried, apart, worst2);
  EXPECT_EQ(run2.loops.tie, SessionTie::kTied);
  EXPECT_GE(cross, 4);  // the tie and loops along run 1's 60 m (one per loop_spacing at most)
  EXPECT_LT(worst_m, 0.3);
  EXPECT_LT(worst_deg, 1.0);
  EXPECT_LT(apart, 0.2);            // in run 1's frame: the 0.64 m of the wrong start are gone
  EXPECT_LT(worst2, worst1 + 0.5);  // as close to the truth as run 1's map lets it be

  // The graph of run 2 holds run 1's keyframes (moved by little) and edges, then its own.
  ASSERT_GT(both.keyframes.size(), n1 + 50);
  for (std::size_t i = 0; i < n1; ++i)
  {
    EXPECT_EQ(both.keyframes[i].session, 0);
    EXPECT_EQ(both.keyframes[i].stamp, saved.keyframes[i].stamp);
    EXPECT_LT(ts::translationError(both.keyframes[i].pose, saved.keyframes[i].pose), 0.1) << "keyframe " << i;
  }
  for (std::size_t i = n1; i < both.keyframes.size(); ++i)
  {
    EXPECT_EQ(both.keyframes[i].session, 1);
  }
  for (std::size_t i = 0; i < saved.edges.size(); ++i)
  {
    EXPECT_EQ(both.edges[i].from, saved.edges[i].from);
    EXPECT_EQ(both.edges[i].to, saved.edges[i].to);
  }
  writeGraphFile(path, both, GraphFileInfo());
  EXPECT_EQ(readGraphFile(path).graph.keyframes.size(), both.keyframes.size());
  std::remove(path.c_str());
}

}  // namespace
}  // namespace aloam
