// KITTI-odometry-style trajectory evaluation: segment drift as defined by the KITTI devkit
// (evaluate_odometry.cpp) and absolute trajectory error after rigid alignment.
#pragma once

#include <cstddef>
#include <limits>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "aloam_nodelet/eval/trajectory_io.h"

namespace aloam
{
namespace eval
{
/// Which frames and segments to evaluate.
struct EvalOptions
{
  /// First frame used. Earlier frames are ignored completely (by drift and by ATE).
  std::size_t start = 0;
  /// Segment lengths in metres (KITTI devkit: 100..800 m). Each must be > 0.
  std::vector<double> segment_lengths{ 100.0, 200.0, 300.0, 400.0, 500.0, 600.0, 700.0, 800.0 };
  /// Stride between the first frames of segments (the devkit uses 10, one per second at 10 Hz). >= 1.
  std::size_t step = 1;
  /// > 0: segments that start or end in a fast turn are left out of the drift: a frame whose ground-truth
  /// yaw changed by more than this many degrees since the frame before, and the `turn_settle_frames` after
  /// it. Shows the drift a trajectory keeps once its turns are over (yaw bursts). 0: every segment.
  double skip_turns_deg = 0.0;
  std::size_t turn_settle_frames = 3;
};

/// Mean errors of all segments of one nominal length (NaN when count == 0).
struct LengthStats
{
  double length = 0.0;
  double translation_drift_percent = std::numeric_limits<double>::quiet_NaN();
  double rotation_deg_per_100m = std::numeric_limits<double>::quiet_NaN();
  std::size_t count = 0;
};

/// Result of evaluate().
struct EvalResult
{
  /// Mean over all segments of |t_err| / L, in percent (NaN if no segment fits).
  double translation_drift_percent = std::numeric_limits<double>::quiet_NaN();
  /// Mean over all segments of angle(R_err) / L, in degrees per 100 m (NaN if no segment fits).
  double rotation_deg_per_100m = std::numeric_limits<double>::quiet_NaN();
  /// RMSE and maximum of the position errors after rigid (no scale) alignment, in metres.
  double ate_rmse_m = std::numeric_limits<double>::quiet_NaN();
  double ate_max_m = std::numeric_limits<double>::quiet_NaN();
  /// Number of segments that entered the drift means.
  std::size_t segments = 0;
  /// Number of frames evaluated (size - start).
  std::size_t frames = 0;
  /// One entry per EvalOptions::segment_lengths entry, in the same order.
  std::vector<LengthStats> per_length;
};

/// Evaluates `est` against `gt` (same frame, e.g. both lidar poses; same length) over frames
/// start..end. Segment drift follows the KITTI devkit: path distances come from the GT; for each first
/// frame (every `step` frames) and length L the last frame is the first one whose distance from the
/// first frame is strictly greater than L (segments without one are skipped);
/// error = (est_first^-1 * est_last)^-1 * (gt_first^-1 * gt_last); t_err = |t(error)| / L and
/// r_err = acos(clamp((trace(R(error)) - 1) / 2)) / L. Matrices are inverted as general 4x4 matrices,
/// as the devkit does. With `skip_turns_deg` some segments are left out (EvalOptions). Throws std::invalid_argument on
/// different lengths, fewer than 2 frames from `start` on, step == 0 or a non-positive segment length.
EvalResult evaluate(const Trajectory& gt, const Trajectory& est, const EvalOptions& options = EvalOptions());

/// Converts KITTI camera-0 poses into lidar poses relative to the first frame's lidar pose:
/// L_i = (P_0 * tr)^-1 * (P_i * tr), where `tr` is the calib.txt `Tr` (velodyne -> camera 0).
/// With tr = identity this simply re-bases a trajectory to its first frame.
Trajectory cameraToLidar(const Trajectory& cam_poses, const Eigen::Isometry3d& tr);

/// Rigid transform T (rotation + translation, no scale) minimising sum |T * src_i - dst_i|^2
/// (Umeyama/Horn closed form via SVD, with the reflection fix so that det(R) = +1).
/// Throws std::invalid_argument if the sizes differ or the inputs are empty.
Eigen::Isometry3d alignRigid(const std::vector<Eigen::Vector3d>& src, const std::vector<Eigen::Vector3d>& dst);

}  // namespace eval
}  // namespace aloam
