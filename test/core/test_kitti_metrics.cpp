// Tests for the KITTI trajectory I/O and evaluation library (aloam::eval).

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "aloam_nodelet/eval/kitti_metrics.h"
#include "aloam_nodelet/eval/trajectory_io.h"

namespace aloam
{
namespace eval
{
namespace
{
constexpr double kRadToDeg = 180.0 / M_PI;

// A file in the temp directory, named after the running test, deleted on destruction.
class TempFile
{
public:
  explicit TempFile(const std::string& suffix)
  {
    const ::testing::TestInfo* info = ::testing::UnitTest::GetInstance()->current_test_info();
    std::random_device random;
    path_ = (std::filesystem::temp_directory_path() /
             ("aloam_eval_" + std::string(info->name()) + "_" + std::to_string(random()) + "_" + suffix))
                .string();
  }
  TempFile(const TempFile&) = delete;
  TempFile& operator=(const TempFile&) = delete;
  ~TempFile()
  {
    std::error_code ignored;
    std::filesystem::remove(path_, ignored);
  }

  const std::string& path() const { return path_; }

  void write(const std::string& content) const
  {
    std::ofstream out(path_);
    out << content;
  }

  std::string read() const
  {
    std::ifstream in(path_);
    std::stringstream buffer;
    buffer << in.rdbuf();
    return buffer.str();
  }

private:
  std::string path_;
};

Eigen::Isometry3d makePose(const Eigen::Vector3d& t, double yaw, double pitch = 0.0, double roll = 0.0)
{
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() =
      (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
       Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
          .toRotationMatrix();
  pose.translation() = t;
  return pose;
}

// Vehicle-like 3-D path: 1 m per frame forward, slowly varying yaw rate and pitch.
Trajectory curvedTrajectory(std::size_t frames)
{
  Trajectory poses;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  for (std::size_t i = 0; i < frames; ++i)
  {
    poses.push_back(pose);
    const double s = static_cast<double>(i);
    const Eigen::Isometry3d step =
        makePose(Eigen::Vector3d(1.0, 0.0, 0.0), 0.02 * std::sin(0.03 * s), 0.004 * std::cos(0.05 * s), 0.001);
    pose = pose * step;
  }
  return poses;
}

// Straight line along x with `spacing` metres between frames.
Trajectory straightLine(std::size_t frames, double spacing)
{
  Trajectory poses;
  for (std::size_t i = 0; i < frames; ++i)
  {
    poses.push_back(makePose(Eigen::Vector3d(spacing * static_cast<double>(i), 0.0, 0.0), 0.0));
  }
  return poses;
}

EvalOptions shortSegments(std::vector<double> lengths)
{
  EvalOptions options;
  options.segment_lengths = std::move(lengths);
  return options;
}

// Expects `fn` to throw std::runtime_error whose message contains every string in `parts`.
template <typename Fn>
void expectRuntimeErrorMentioning(Fn fn, const std::vector<std::string>& parts)
{
  try
  {
    fn();
    ADD_FAILURE() << "no exception thrown";
  }
  catch (const std::runtime_error& e)
  {
    const std::string message = e.what();
    for (const std::string& part : parts)
    {
      EXPECT_NE(message.find(part), std::string::npos) << "'" << message << "' does not mention '" << part << "'";
    }
  }
}

// ---------------------------------------------------------------------------------------------------
// evaluate(): segment drift

TEST(KittiMetrics, IdenticalTrajectoriesGiveZeroErrors)
{
  const Trajectory gt = curvedTrajectory(300);
  const EvalResult result = evaluate(gt, gt, shortSegments({ 10, 20, 50, 100 }));
  EXPECT_EQ(result.frames, 300u);
  EXPECT_GT(result.segments, 0u);
  EXPECT_NEAR(result.translation_drift_percent, 0.0, 1e-9);
  EXPECT_NEAR(result.rotation_deg_per_100m, 0.0, 1e-4);
  EXPECT_NEAR(result.ate_rmse_m, 0.0, 1e-9);
  EXPECT_NEAR(result.ate_max_m, 0.0, 1e-9);
  ASSERT_EQ(result.per_length.size(), 4u);
  std::size_t total = 0;
  for (const LengthStats& stats : result.per_length)
  {
    EXPECT_GT(stats.count, 0u);
    total += stats.count;
  }
  EXPECT_EQ(total, result.segments);
}

TEST(KittiMetrics, IdenticalNonOrthonormalPosesGiveZeroRotationError)
{
  // GT files carry ~7 significant digits, so their rotations are not exactly orthonormal. Inverting
  // them as rigid transforms (transpose) would produce a spurious rotation error of ~0.1 deg/100m.
  Trajectory gt = curvedTrajectory(200);
  for (Eigen::Isometry3d& pose : gt)
  {
    for (int r = 0; r < 3; ++r)
    {
      for (int c = 0; c < 4; ++c)
      {
        char text[32];
        std::snprintf(text, sizeof(text), "%.6e", pose.matrix()(r, c));
        pose.matrix()(r, c) = std::strtod(text, nullptr);
      }
    }
  }
  const EvalResult result = evaluate(gt, gt, shortSegments({ 10, 20, 50 }));
  EXPECT_GT(result.segments, 0u);
  EXPECT_NEAR(result.translation_drift_percent, 0.0, 1e-7);
  EXPECT_NEAR(result.rotation_deg_per_100m, 0.0, 1e-4);
}

TEST(KittiMetrics, ScaledTranslationGivesTwoPercentDrift)
{
  const Trajectory gt = straightLine(1000, 0.1);
  Trajectory est = gt;
  for (Eigen::Isometry3d& pose : est)
  {
    pose.translation() *= 1.02;
  }
  const EvalResult result = evaluate(gt, est, shortSegments({ 10, 20, 50 }));
  EXPECT_GT(result.segments, 0u);
  // Each segment ends at most one frame (0.1 m) beyond L: drift in [2.0, 2.02] %.
  EXPECT_GE(result.translation_drift_percent, 2.0 - 1e-9);
  EXPECT_LE(result.translation_drift_percent, 2.02 + 1e-9);
  EXPECT_NEAR(result.rotation_deg_per_100m, 0.0, 1e-9);
  for (const LengthStats& stats : result.per_length)
  {
    EXPECT_NEAR(stats.translation_drift_percent, 2.0, 0.021);
  }
}

TEST(KittiMetrics, SegmentEndsAtFirstFrameStrictlyBeyondLength)
{
  // Devkit rule: last frame = first one with dist > dist[first] + L. With exactly 1 m per frame and
  // L = 5 m that is first + 6, so a 2 % scale error shows up as 2 % * 6 / 5 = 2.4 %.
  const Trajectory gt = straightLine(20, 1.0);
  Trajectory est = gt;
  for (Eigen::Isometry3d& pose : est)
  {
    pose.translation() *= 1.02;
  }
  const EvalResult result = evaluate(gt, est, shortSegments({ 5 }));
  EXPECT_EQ(result.segments, 14u);  // first frames 0..13
  EXPECT_NEAR(result.translation_drift_percent, 2.4, 1e-9);

  EvalOptions strided = shortSegments({ 5 });
  strided.step = 5;
  EXPECT_EQ(evaluate(gt, est, strided).segments, 3u);  // first frames 0, 5, 10
}

TEST(KittiMetrics, ErrorIsComposedInDevkitOrder)
{
  // One segment (frames 0 -> 2, L = 1.5 m). The estimate ends at the right place with a 90 deg wrong
  // heading: inverse(est_delta) * gt_delta has zero translation (gt_delta * inverse(est_delta) would not).
  const Trajectory gt = straightLine(3, 1.0);
  Trajectory est = gt;
  est[2] = makePose(Eigen::Vector3d(2.0, 0.0, 0.0), M_PI / 2);
  const EvalResult result = evaluate(gt, est, shortSegments({ 1.5 }));
  ASSERT_EQ(result.segments, 1u);
  EXPECT_NEAR(result.translation_drift_percent, 0.0, 1e-9);
  EXPECT_NEAR(result.rotation_deg_per_100m, 90.0 / 1.5 * 100.0, 1e-6);
}

TEST(KittiMetrics, ConstantYawBiasGivesExpectedRotationError)
{
  const double bias = 0.001;  // rad per frame, 1 m per frame
  const Trajectory gt = straightLine(600, 1.0);
  Trajectory est;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  const Eigen::Isometry3d step = makePose(Eigen::Vector3d(1.0, 0.0, 0.0), bias);
  for (std::size_t i = 0; i < gt.size(); ++i)
  {
    est.push_back(pose);
    pose = pose * step;
  }
  const EvalResult result = evaluate(gt, est, shortSegments({ 100, 200, 300, 400 }));
  // A segment of L m spans L + 1 frames, i.e. (L + 1) * bias rad: within 1 % above bias per metre.
  const double nominal = bias * kRadToDeg * 100.0;  // 5.73 deg / 100 m
  EXPECT_GT(result.segments, 0u);
  EXPECT_GE(result.rotation_deg_per_100m, nominal);
  EXPECT_LE(result.rotation_deg_per_100m, nominal * 1.0101);
  EXPECT_GT(result.translation_drift_percent, 0.0);
}

// A drive with one 60 deg turn in two 30 deg steps, estimated 2 deg late in the turn and right after it:
// the error lives only in the turn and the frames just after, which skip_turns_deg leaves out.
TEST(KittiMetrics, SkipTurnsLeavesOutSegmentsEndingInATurn)
{
  const std::size_t frames = 60;
  const std::size_t turn = 30;  // frames 30 and 31 turn by 30 deg each
  Trajectory gt;
  Trajectory est;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  for (std::size_t i = 0; i < frames; ++i)
  {
    const bool turning = i == turn || i == turn + 1;
    pose = pose * makePose(Eigen::Vector3d(1.0, 0.0, 0.0), turning ? 30.0 / kRadToDeg : 0.0);
    gt.push_back(pose);
    const bool late = i >= turn && i <= turn + 2;
    est.push_back(late ? pose * makePose(Eigen::Vector3d::Zero(), -2.0 / kRadToDeg) : pose);
  }
  EvalOptions options = shortSegments({ 5, 10 });
  const EvalResult every = evaluate(gt, est, options);
  options.skip_turns_deg = 3.0;
  const EvalResult steady = evaluate(gt, est, options);
  EXPECT_GT(every.rotation_deg_per_100m, 1.0);
  EXPECT_NEAR(steady.rotation_deg_per_100m, 0.0, 1e-9);
  // Segments starting or ending at frames 30..34 (the two turn frames and 3 after the last) are out.
  EXPECT_LT(steady.segments, every.segments);
  EXPECT_GE(steady.segments + 2 * 2 * 5, every.segments);  // at most 5 starts and 5 ends per length
  options.skip_turns_deg = 40.0;                           // no step turns that far: every segment stays
  EXPECT_EQ(evaluate(gt, est, options).segments, every.segments);
  options.skip_turns_deg = -1.0;
  EXPECT_THROW(evaluate(gt, est, options), std::invalid_argument);
}

TEST(KittiMetrics, NoSegmentFitsGivesNanWithoutThrowing)
{
  const Trajectory gt = straightLine(20, 1.0);
  EvalResult result;
  ASSERT_NO_THROW(result = evaluate(gt, gt, EvalOptions()));
  EXPECT_EQ(result.segments, 0u);
  EXPECT_TRUE(std::isnan(result.translation_drift_percent));
  EXPECT_TRUE(std::isnan(result.rotation_deg_per_100m));
  EXPECT_NEAR(result.ate_rmse_m, 0.0, 1e-12);
  ASSERT_EQ(result.per_length.size(), 8u);
  EXPECT_DOUBLE_EQ(result.per_length.front().length, 100.0);
  EXPECT_DOUBLE_EQ(result.per_length.back().length, 800.0);
  for (const LengthStats& stats : result.per_length)
  {
    EXPECT_EQ(stats.count, 0u);
    EXPECT_TRUE(std::isnan(stats.translation_drift_percent));
  }
}

TEST(KittiMetrics, StartExcludesEarlierFrames)
{
  const Trajectory gt = curvedTrajectory(300);
  Trajectory est = gt;
  const Eigen::Isometry3d big_error = makePose(Eigen::Vector3d(5.0, -3.0, 2.0), 0.5, 0.1, -0.2);
  for (std::size_t i = 0; i < 10; ++i)
  {
    est[i] = est[i] * big_error;
  }
  EvalOptions options = shortSegments({ 10, 20, 50 });
  options.start = 10;
  const EvalResult after = evaluate(gt, est, options);
  EXPECT_EQ(after.frames, 290u);
  EXPECT_GT(after.segments, 0u);
  EXPECT_NEAR(after.translation_drift_percent, 0.0, 1e-9);
  EXPECT_NEAR(after.rotation_deg_per_100m, 0.0, 1e-4);
  EXPECT_NEAR(after.ate_rmse_m, 0.0, 1e-9);

  options.start = 0;
  const EvalResult all = evaluate(gt, est, options);
  EXPECT_GT(all.translation_drift_percent, 0.1);
  EXPECT_GT(all.ate_max_m, 1.0);
}

// ---------------------------------------------------------------------------------------------------
// evaluate(): ATE

TEST(KittiMetrics, RigidlyTransformedCopyHasZeroAte)
{
  const Trajectory gt = curvedTrajectory(300);
  const Eigen::Isometry3d offset = makePose(Eigen::Vector3d(12.0, -40.0, 3.0), 1.2, -0.3, 0.7);
  Trajectory est;
  for (const Eigen::Isometry3d& pose : gt)
  {
    est.push_back(offset * pose);
  }
  const EvalResult result = evaluate(gt, est, shortSegments({ 10, 50 }));
  EXPECT_NEAR(result.ate_rmse_m, 0.0, 1e-9);
  EXPECT_NEAR(result.ate_max_m, 0.0, 1e-9);
  EXPECT_NEAR(result.translation_drift_percent, 0.0, 1e-9);
}

TEST(KittiMetrics, NoisyCopyGivesExpectedAteRmse)
{
  // Every GT pose appears twice; the estimate is displaced by +e and -e along a fixed direction on
  // the two copies. The noise has zero mean and zero cross-covariance with the path, so the best
  // alignment is the identity and every residual is exactly e.
  const double e = 0.07;
  const Eigen::Vector3d direction = Eigen::Vector3d(0.6, 0.0, 0.8);
  const Trajectory path = curvedTrajectory(150);
  Trajectory gt;
  Trajectory est;
  for (const Eigen::Isometry3d& pose : path)
  {
    for (const double sign : { 1.0, -1.0 })
    {
      gt.push_back(pose);
      Eigen::Isometry3d noisy = pose;
      noisy.translation() += sign * e * direction;
      est.push_back(noisy);
    }
  }
  // A rigid offset on top must not change anything.
  const Eigen::Isometry3d offset = makePose(Eigen::Vector3d(-5.0, 2.0, 1.0), -0.4);
  for (Eigen::Isometry3d& pose : est)
  {
    pose = offset * pose;
  }
  const EvalResult result = evaluate(gt, est, shortSegments({ 10 }));
  EXPECT_NEAR(result.ate_rmse_m, e, 1e-9);
  EXPECT_NEAR(result.ate_max_m, e, 1e-9);
}

TEST(KittiMetrics, AteAlignmentHasNoScale)
{
  const Trajectory gt = curvedTrajectory(200);
  Trajectory est = gt;
  for (Eigen::Isometry3d& pose : est)
  {
    pose.translation() *= 1.1;
  }
  // A similarity alignment would make this zero; a rigid one cannot.
  EXPECT_GT(evaluate(gt, est, shortSegments({ 10 })).ate_rmse_m, 1.0);
}

TEST(KittiMetrics, AteAlignmentCannotReflect)
{
  const Trajectory gt = curvedTrajectory(200);
  Trajectory est = gt;
  for (Eigen::Isometry3d& pose : est)
  {
    pose.translation().y() = -pose.translation().y();  // mirror image: only a reflection would fit
  }
  EXPECT_GT(evaluate(gt, est, shortSegments({ 10 })).ate_rmse_m, 1.0);
}

TEST(KittiMetrics, AlignRigidRecoversTransformAndReturnsProperRotation)
{
  const Eigen::Isometry3d truth = makePose(Eigen::Vector3d(1.0, 2.0, -3.0), 2.5, 0.2, -1.0);
  std::vector<Eigen::Vector3d> src;
  std::vector<Eigen::Vector3d> dst;
  std::vector<Eigen::Vector3d> planar_src;
  for (int i = 0; i < 30; ++i)
  {
    const Eigen::Vector3d p(std::cos(0.3 * i) * i, std::sin(0.2 * i) * 5.0, 0.1 * i * i - 3.0);
    src.push_back(p);
    dst.push_back(truth * p);
    planar_src.push_back(Eigen::Vector3d(p.x(), p.y(), 0.0));
  }
  const Eigen::Isometry3d found = alignRigid(src, dst);
  EXPECT_TRUE(found.matrix().isApprox(truth.matrix(), 1e-9));

  // Planar points leave the normal direction to the reflection fix.
  const Eigen::Isometry3d planar = alignRigid(planar_src, planar_src);
  EXPECT_NEAR(planar.linear().determinant(), 1.0, 1e-9);
  EXPECT_TRUE(planar.linear().isApprox(Eigen::Matrix3d::Identity(), 1e-9));

  EXPECT_THROW(alignRigid(src, std::vector<Eigen::Vector3d>(3)), std::invalid_argument);
  EXPECT_THROW(alignRigid({}, {}), std::invalid_argument);
}

// ---------------------------------------------------------------------------------------------------
// evaluate(): argument checks

TEST(KittiMetrics, InvalidArgumentsThrow)
{
  const Trajectory gt = curvedTrajectory(50);
  const Trajectory shorter(gt.begin(), gt.end() - 1);
  EXPECT_THROW(evaluate(gt, shorter, EvalOptions()), std::invalid_argument);
  EXPECT_THROW(evaluate(Trajectory(1, Eigen::Isometry3d::Identity()), Trajectory(1, Eigen::Isometry3d::Identity()),
                        EvalOptions()),
               std::invalid_argument);

  EvalOptions options;
  options.start = 49;  // one frame left
  EXPECT_THROW(evaluate(gt, gt, options), std::invalid_argument);
  options.start = 1000;
  EXPECT_THROW(evaluate(gt, gt, options), std::invalid_argument);
  options.start = 48;  // two frames left: fine
  EXPECT_NO_THROW(evaluate(gt, gt, options));

  EvalOptions zero_step;
  zero_step.step = 0;
  EXPECT_THROW(evaluate(gt, gt, zero_step), std::invalid_argument);
  EXPECT_THROW(evaluate(gt, gt, shortSegments({ 10, -5 })), std::invalid_argument);
  EXPECT_THROW(evaluate(gt, gt, shortSegments({ 0 })), std::invalid_argument);
}

// ---------------------------------------------------------------------------------------------------
// cameraToLidar()

TEST(KittiMetrics, CameraToLidarOnKnownExample)
{
  // Lidar x forward / y left / z up; camera x right / y down / z forward. tr maps lidar -> camera.
  Eigen::Isometry3d tr = Eigen::Isometry3d::Identity();
  tr.linear() << 0, -1, 0, 0, 0, -1, 1, 0, 0;
  tr.translation() = Eigen::Vector3d(0.1, -0.05, -0.3);

  // Camera drives 2 m forward (camera z), then turns left by a (rotation about camera -y).
  const double a = 0.2;
  Eigen::Isometry3d cam1 = Eigen::Isometry3d::Identity();
  cam1.translation() = Eigen::Vector3d(0.0, 0.0, 2.0);
  Eigen::Isometry3d cam2 = cam1;
  cam2.linear() = Eigen::AngleAxisd(-a, Eigen::Vector3d::UnitY()).toRotationMatrix();

  // An arbitrary world placement of the camera track must cancel out.
  const Eigen::Isometry3d world = makePose(Eigen::Vector3d(7.0, 8.0, 9.0), 0.3, 0.2, 0.1);
  const Trajectory cam = { world, world * cam1, world * cam2 };
  const Trajectory lidar = cameraToLidar(cam, tr);
  ASSERT_EQ(lidar.size(), 3u);

  EXPECT_TRUE(lidar[0].matrix().isApprox(Eigen::Matrix4d::Identity(), 1e-12));

  // Pure translation: the lidar moves 2 m along its x axis.
  EXPECT_TRUE(lidar[1].linear().isApprox(Eigen::Matrix3d::Identity(), 1e-12));
  EXPECT_TRUE(lidar[1].translation().isApprox(Eigen::Vector3d(2.0, 0.0, 0.0), 1e-12));

  // Left turn = positive yaw about the lidar z axis; the lidar (offset from the camera) swings.
  const Eigen::Isometry3d expected = tr.inverse() * cam2 * tr;
  EXPECT_TRUE(lidar[2].linear().isApprox(Eigen::AngleAxisd(a, Eigen::Vector3d::UnitZ()).toRotationMatrix(), 1e-12));
  EXPECT_TRUE(lidar[2].matrix().isApprox(expected.matrix(), 1e-12));

  EXPECT_TRUE(cameraToLidar(Trajectory(), tr).empty());
}

// ---------------------------------------------------------------------------------------------------
// trajectory_io

TEST(TrajectoryIo, KittiRoundTrip)
{
  const Trajectory poses = curvedTrajectory(40);
  TempFile file("poses.txt");
  writeKittiPoses(file.path(), poses);

  const std::string text = file.read();
  std::istringstream lines(text);
  std::string line;
  std::size_t line_count = 0;
  while (std::getline(lines, line))
  {
    ++line_count;
    std::istringstream fields(line);
    double value = 0.0;
    int numbers = 0;
    while (fields >> value)
    {
      ++numbers;
    }
    EXPECT_EQ(numbers, 12);
  }
  EXPECT_EQ(line_count, poses.size());

  const Trajectory read = readKittiPoses(file.path());
  ASSERT_EQ(read.size(), poses.size());
  for (std::size_t i = 0; i < poses.size(); ++i)
  {
    // 17 significant digits: the round trip is bit-exact.
    EXPECT_TRUE(read[i].matrix() == poses[i].matrix()) << "pose " << i;
  }
}

TEST(TrajectoryIo, ReadSkipsBlankLinesAndKeepsRowMajorOrder)
{
  TempFile file("blank.txt");
  file.write(
      "\n1 0 0 0 0 1 0 0 0 0 1 0\n\n   \t\n"
      "1 2 3 4 5 6 7 8 9 10 11 12\r\n");
  const Trajectory poses = readKittiPoses(file.path());
  ASSERT_EQ(poses.size(), 2u);
  EXPECT_TRUE(poses[0].matrix().isApprox(Eigen::Matrix4d::Identity()));
  EXPECT_DOUBLE_EQ(poses[1].matrix()(0, 1), 2.0);
  EXPECT_DOUBLE_EQ(poses[1].matrix()(0, 3), 4.0);
  EXPECT_DOUBLE_EQ(poses[1].matrix()(1, 0), 5.0);
  EXPECT_DOUBLE_EQ(poses[1].matrix()(2, 3), 12.0);
  EXPECT_DOUBLE_EQ(poses[1].matrix()(3, 3), 1.0);
}

TEST(TrajectoryIo, MalformedPoseFileThrowsWithLocation)
{
  const std::string good = "1 0 0 0 0 1 0 0 0 0 1 0\n";
  const std::vector<std::string> bad_lines = {
    "1 0 0 0 0 1 0 0 0 0 1\n",       // 11 numbers
    "1 0 0 0 0 1 0 0 0 0 1 0 7\n",   // 13 numbers
    "1 0 0 0 0 1 0 0 0 0 1 abc\n",   // not a number
    "1 0 0 0 0 1 0 0 0 0 1 0.5x\n",  // trailing garbage
    "1 0 0 0 0 1 0 0 0 0 1 nan\n",   // not finite
  };
  for (const std::string& bad : bad_lines)
  {
    TempFile file("bad.txt");
    file.write(good + "\n" + bad + good);
    expectRuntimeErrorMentioning([&]() { readKittiPoses(file.path()); }, { file.path(), ":3" });
  }
  expectRuntimeErrorMentioning([]() { readKittiPoses("/nonexistent/dir/poses.txt"); },
                               { "/nonexistent/dir/poses.txt" });
}

TEST(TrajectoryIo, CalibTrParsing)
{
  TempFile file("calib.txt");
  file.write(
      "P0: 7.188560000000e+02 0 6.071928000000e+02 0 0 7.188560000000e+02 1.852157000000e+02 0 0 0 1 0\n"
      "P1: 7.188560000000e+02 0 6.071928000000e+02 -3.861448000000e+02 0 7.188560000000e+02 "
      "1.852157000000e+02 0 0 0 1 0\n"
      "Tr: 4.276802385584e-04 -9.999672484946e-01 -8.084491683471e-03 -1.198459927713e-02 "
      "-7.210626507497e-03 8.081198471645e-03 -9.999413164504e-01 -5.403984729748e-02 "
      "9.999738645903e-01 4.859485810390e-04 -7.206933692422e-03 -2.921968648686e-01\n");
  const Eigen::Isometry3d tr = readKittiCalibTr(file.path());
  EXPECT_DOUBLE_EQ(tr.matrix()(0, 0), 4.276802385584e-04);
  EXPECT_DOUBLE_EQ(tr.matrix()(0, 1), -9.999672484946e-01);
  EXPECT_DOUBLE_EQ(tr.matrix()(0, 3), -1.198459927713e-02);
  EXPECT_DOUBLE_EQ(tr.matrix()(1, 2), -9.999413164504e-01);
  EXPECT_DOUBLE_EQ(tr.matrix()(2, 0), 9.999738645903e-01);
  EXPECT_DOUBLE_EQ(tr.matrix()(2, 3), -2.921968648686e-01);
  EXPECT_EQ(tr.matrix().row(3), Eigen::RowVector4d(0, 0, 0, 1));

  TempFile missing("calib_missing.txt");
  missing.write("P0: 1 0 0 0 0 1 0 0 0 0 1 0\n");
  expectRuntimeErrorMentioning([&]() { readKittiCalibTr(missing.path()); }, { missing.path(), "Tr:" });

  TempFile malformed("calib_malformed.txt");
  malformed.write("P0: 1 0 0 0 0 1 0 0 0 0 1 0\nTr: 1 0 0 0 0 1 0 0 0 0 1\n");
  expectRuntimeErrorMentioning([&]() { readKittiCalibTr(malformed.path()); }, { malformed.path(), ":2" });
}

TEST(TrajectoryIo, ReadTimes)
{
  TempFile file("times.txt");
  file.write("0.000000e+00\n1.036630e-01\n\n2.072599e-01\n");
  const std::vector<double> times = readTimes(file.path());
  ASSERT_EQ(times.size(), 3u);
  EXPECT_DOUBLE_EQ(times[1], 0.103663);
  EXPECT_DOUBLE_EQ(times[2], 0.2072599);

  TempFile bad("times_bad.txt");
  bad.write("0.0\n0.1 0.2\n");
  expectRuntimeErrorMentioning([&]() { readTimes(bad.path()); }, { bad.path(), ":2" });
}

TEST(TrajectoryIo, WriteTum)
{
  const double yaw = 0.8;
  const Trajectory poses = { makePose(Eigen::Vector3d(1.0, 2.0, 3.0), yaw),
                             makePose(Eigen::Vector3d(-4.0, 5.5, 0.25), 3.5) };
  TempFile file("tum.txt");
  writeTumTrajectory(file.path(), poses, { 1234.5, 1234.6 });

  std::istringstream lines(file.read());
  std::vector<std::vector<double>> rows;
  std::string line;
  while (std::getline(lines, line))
  {
    std::istringstream fields(line);
    std::vector<double> row;
    double value = 0.0;
    while (fields >> value)
    {
      row.push_back(value);
    }
    rows.push_back(row);
  }
  ASSERT_EQ(rows.size(), 2u);
  ASSERT_EQ(rows[0].size(), 8u);
  EXPECT_NEAR(rows[0][0], 1234.5, 1e-9);
  EXPECT_NEAR(rows[0][1], 1.0, 1e-9);
  EXPECT_NEAR(rows[0][2], 2.0, 1e-9);
  EXPECT_NEAR(rows[0][3], 3.0, 1e-9);
  EXPECT_NEAR(rows[0][4], 0.0, 1e-9);
  EXPECT_NEAR(rows[0][5], 0.0, 1e-9);
  EXPECT_NEAR(rows[0][6], std::sin(yaw / 2), 1e-9);
  EXPECT_NEAR(rows[0][7], std::cos(yaw / 2), 1e-9);
  // yaw = 3.5 rad: (0, 0, sin 1.75, cos 1.75) has w < 0, so the written quaternion is its negative.
  EXPECT_NEAR(rows[1][6], -std::sin(1.75), 1e-9);
  EXPECT_NEAR(rows[1][7], -std::cos(1.75), 1e-9);

  EXPECT_THROW(writeTumTrajectory(file.path(), poses, { 1.0 }), std::invalid_argument);
}

}  // namespace
}  // namespace eval
}  // namespace aloam
